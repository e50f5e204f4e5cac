"""What the agent sees: its camera's RGB (uint8), depth (float32 m) and instance ids (int32), every agent's view
rendered in one call of the scene's renderer (render/backends.py: the CPU splat renderer or gsplat)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from sagebench.render.backends import Renderer
from sagebench.render.camera import agent_camera

IMAGE_KEYS = ("rgb", "depth", "instance")


def to_uint8(rgb: np.ndarray) -> np.ndarray:
    """[H, W, 3] float colour -> uint8, clipped to [0, 1] and rounded (as render's PNGs)."""
    return (np.clip(rgb, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def observe(renderer: Renderer, poses: np.ndarray, keys: Sequence[str], *, floor_z: float,
            camera_height: float, hfov_deg: float, width: int, height: int) -> list[dict[str, np.ndarray]]:
    """The images named in `keys` (a subset of IMAGE_KEYS) for agents at poses [B, >=3] (x, y, ..., yaw last)."""
    poses = np.atleast_2d(poses)
    cams = [agent_camera(float(p[0]), float(p[1]), float(p[-1]), floor_z=floor_z, camera_height=camera_height,
                         hfov_deg=hfov_deg, width=width, height=height) for p in poses]
    out = []
    for frame in renderer.render(cams):
        images = {"rgb": lambda f=frame: to_uint8(f.rgb), "depth": lambda f=frame: f.depth.astype(np.float32),
                  "instance": lambda f=frame: f.instance.astype(np.int32)}
        out.append({k: images[k]() for k in keys})
    return out
