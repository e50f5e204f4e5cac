"""What the agents see: their cameras' RGB (uint8), depth (float32 m) and instance ids (int32), every agent's view
rendered in one call of the scene's renderer (render/backends.py: the CPU splat renderer or gsplat) and handed
back as one array per image over the batch (render/observations.py)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from sagebench.render.backends import Renderer
from sagebench.render.camera import agent_cameras


def observe(renderer: Renderer, poses: np.ndarray, keys: Sequence[str], *, floor_z: float,
            camera_height: float, hfov_deg: float, width: int, height: int) -> dict[str, np.ndarray]:
    """The images named in `keys` (of rgb, depth, instance) for agents at poses [B, >=3] (x, y, ..., yaw last):
    [B, H, W(, 3)] each, row b the agent at poses[b]."""
    cams = agent_cameras(poses, floor_z=floor_z, camera_height=camera_height, hfov_deg=hfov_deg, width=width,
                         height=height)
    return renderer.observe(cams, keys)
