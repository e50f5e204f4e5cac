"""sagebench's Gaussians and cameras as gsplat's `rasterization` takes them, and its output back as Frames: the one
place where the two conventions meet (numpy only; tests check every convention against the CPU renderer).

What each side stores, and what is converted:
- quaternions: both w first (INRIA layout, gsplat's `quats`); gsplat normalises them too, so they pass as they are.
- scales: sagebench keeps the log of each standard deviation, gsplat takes the deviation: exp.
- opacity: sagebench keeps the logit, gsplat takes the opacity: sigmoid.
- colour: SH coefficients [N, K, 3], DC first, degree 0..3 in the reference rasterisers' basis and signs, which
  gsplat evaluates the same way (view direction = centre minus camera position), + 0.5 and clamped at 0.
- camera: both take a world-to-camera matrix with OpenCV axes (x right, y down, z forward) and pixel centres at
  (j + 0.5, i + 0.5); the intrinsics become K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]. The world is Z up on
  both sides: the matrix carries it, nothing is flipped.
- near plane 0.01 m and the 0.3 px^2 added to every 2D covariance are the CPU renderer's constants; gsplat's
  clamp of x/z to 1.3 tan(fov/2) matches the CPU renderer's for a centred principal point (sagebench's cameras
  always have one).
- depth: gsplat's "RGB+ED" mode gives the expected z-depth (sum w z / sum w), the CPU renderer's depth; where
  nothing was drawn both give 0.

Where they differ, by design of each renderer: gsplat caps alpha at 0.999 (the CPU renderer at 0.99), keeps
a Gaussian out to 3.33 sigma per axis (the CPU renderer to its 3-sigma ellipse) and renders no instance ids.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sagebench.render.camera import Camera
from sagebench.render.gaussians import Gaussians
from sagebench.render.splat_reference import DILATION, NEAR, Frame

RENDER_MODE = "RGB+ED"  # colour and expected depth in one pass
RASTERIZE_MODE = "classic"  # no antialiasing compensation of opacities: the CPU renderer has none


@dataclass(frozen=True)
class GsplatScene:
    """The Gaussians as gsplat's `rasterization` takes them (float32, N Gaussians, K = (degree + 1)^2).

    means [N, 3] m, quats [N, 4] wxyz, scales [N, 3] standard deviations m, opacities [N] in (0, 1),
    colors [N, K, 3] SH coefficients, sh_degree 0..3.
    """

    means: np.ndarray
    quats: np.ndarray
    scales: np.ndarray
    opacities: np.ndarray
    colors: np.ndarray
    sh_degree: int


@dataclass(frozen=True)
class GsplatCameras:
    """C cameras of one size as gsplat takes them: viewmats [C, 4, 4] world-to-camera, Ks [C, 3, 3] (float32)."""

    viewmats: np.ndarray
    Ks: np.ndarray
    width: int
    height: int


def scene_arrays(g: Gaussians) -> GsplatScene:
    """The Gaussians in gsplat's parameterisation (module docstring)."""
    return GsplatScene(
        means=np.ascontiguousarray(g.means, np.float32),
        quats=np.ascontiguousarray(g.quats_wxyz, np.float32),
        scales=np.exp(g.log_scales.astype(np.float64)).astype(np.float32),
        opacities=(1.0 / (1.0 + np.exp(-g.opacity_logits.astype(np.float64)))).astype(np.float32),
        colors=np.ascontiguousarray(g.sh, np.float32),
        sh_degree=g.sh_degree,
    )


def camera_arrays(cams: Sequence[Camera]) -> GsplatCameras:
    """Cameras (all of one image size) as viewmats and Ks."""
    if not cams:
        raise ValueError("no cameras")
    sizes = {(c.width, c.height) for c in cams}
    if len(sizes) > 1:
        raise ValueError(f"one gsplat call renders one image size, got {sorted(sizes)}")
    ks = np.zeros((len(cams), 3, 3), np.float32)
    for k, c in enumerate(cams):
        ks[k] = [[c.fx, 0.0, c.cx], [0.0, c.fy, c.cy], [0.0, 0.0, 1.0]]
    viewmats = np.stack([np.asarray(c.world_to_camera, np.float64) for c in cams]).astype(np.float32)
    return GsplatCameras(viewmats=viewmats, Ks=ks, width=cams[0].width, height=cams[0].height)


def raster_settings() -> dict:
    """The keyword arguments of gsplat's `rasterization` that carry the CPU renderer's constants."""
    return {"near_plane": NEAR, "eps2d": DILATION, "render_mode": RENDER_MODE, "rasterize_mode": RASTERIZE_MODE,
            "tile_size": 16}


def frames_from_gsplat(colors: np.ndarray, alphas: np.ndarray) -> list[Frame]:
    """gsplat's output, colors [C, H, W, 4] (RGB + expected depth) and alphas [C, H, W, 1], as C Frames (no
    instance ids); depth is 0 where nothing was drawn, as the CPU renderer's."""
    colors, alphas = np.asarray(colors, np.float32), np.asarray(alphas, np.float32)
    if colors.ndim != 4 or colors.shape[-1] != 4 or alphas.shape != colors.shape[:-1] + (1,):
        raise ValueError(f"expected colors [C, H, W, 4] and alphas [C, H, W, 1], got {colors.shape}, {alphas.shape}")
    frames = []
    for rgbd, a in zip(colors, alphas[..., 0]):
        depth = np.where(a > 0.0, rgbd[..., 3], 0.0).astype(np.float32)
        frames.append(Frame(rgb=np.ascontiguousarray(rgbd[..., :3]), depth=depth, alpha=np.ascontiguousarray(a),
                            instance=None))
    return frames
