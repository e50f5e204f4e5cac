"""Compile (or load from numba's on-disk cache) every JIT kernel a run's tasks call, once, before they fan out.

Kernels are cached per signature (`cache=True`), so a run that starts N workers with a cold cache would compile
each kernel N times side by side; warming them here with tiny inputs of the types the stages pass writes the
cache once, and every worker then only loads it.
"""

from __future__ import annotations

import numpy as np


def compile_kernels() -> None:
    """Call each JIT kernel of the stages once on tiny inputs of the real argument types."""
    from sagebench.astar.grid_astar import astar
    from sagebench.astar.shortcut import shortcut_indices
    from sagebench.collider_export.quality import _inside
    from sagebench.metrics.dtw import dtw
    from sagebench.render.camera import agent_camera
    from sagebench.render.chunks import pack
    from sagebench.render.gaussians import Gaussians
    from sagebench.render.splat_render import contributions, render, render_packed

    nav = np.ones((4, 4), dtype=np.uint8)
    path = astar(nav, (0, 0), (3, 3), 0.05)
    shortcut_indices(nav, path.cells)
    dtw(np.zeros((2, 2)), np.ones((3, 2)))
    _inside(np.zeros((1, 3)), np.array([[1.0, 0.0, 0.0, 1.0]]))
    g = Gaussians(means=np.array([[1.0, 0.0, 1.2], [2.0, 0.1, 1.1]], np.float32),
                  quats_wxyz=np.tile(np.array([1, 0, 0, 0], np.float32), (2, 1)),
                  log_scales=np.full((2, 3), -3.0, np.float32), opacity_logits=np.zeros(2, np.float32),
                  sh=np.zeros((2, 1, 3), np.float32), instance_id=np.ones(2, np.int32))
    cam = agent_camera(0.0, 0.0, 0.0, width=16, height=16)
    render(g, cam)
    contributions(g, cam)
    render_packed(pack(g), [cam, cam])
