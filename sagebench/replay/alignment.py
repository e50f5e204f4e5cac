"""Appearance/physics alignment: collider depth by ray casting, compared with the rendered splat depth.

For a grid of pixels of an agent-camera view, a ray from the camera centre through each pixel centre is
cast against the MuJoCo colliders; its hit distance, measured along the camera's optical axis, is the
depth the colliders would show there. Where the rendered Gaussians are opaque (alpha >= min_alpha) and a
collider was hit, the median absolute difference to the splat depth says how well the two layers line up:
a Gaussian layer shifted or rotated against the colliders (a failure of published pipelines) shows as a
median of tens of centimetres, an aligned one as the splats' own thickness of a few.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from sagebench.render.camera import Camera


@dataclass(frozen=True)
class PixelGrid:
    """Pixel centres sampled every `stride` px: rows [R] and cols [C] int (image indices)."""

    rows: np.ndarray
    cols: np.ndarray


def pixel_grid(camera: Camera, stride: int) -> PixelGrid:
    """Every `stride`-th pixel in each direction, offset by half a stride so the grid is centred."""
    if stride < 1:
        raise ValueError(f"stride must be >= 1, got {stride}")
    return PixelGrid(rows=np.arange(stride // 2, camera.height, stride), cols=np.arange(stride // 2, camera.width, stride))


def ray_directions(camera: Camera, grid: PixelGrid) -> np.ndarray:
    """[R, C, 3] world directions through the pixel centres, scaled so their camera-z component is 1."""
    u = grid.cols + 0.5
    v = grid.rows + 0.5
    x = (u[None, :] - camera.cx) / camera.fx
    y = (v[:, None] - camera.cy) / camera.fy
    cam = np.stack(np.broadcast_arrays(x, y, np.ones_like(x * y)), axis=-1)  # [R, C, 3] camera frame
    return cam @ camera.world_to_camera[:3, :3]  # rows times R, i.e. R^T applied to each vector


def collider_depth(model: mujoco.MjModel, data: mujoco.MjData, camera: Camera, grid: PixelGrid, *,
                   bodyexclude: int = -1) -> np.ndarray:
    """[R, C] camera-z depth (m) of the nearest collider along each grid pixel's ray; NaN where none.

    `data` must hold the model's geom poses (after mj_kinematics or a step); `bodyexclude` (e.g. the agent)
    is ignored. One `mj_multiRay` call for all rays.
    """
    vec = ray_directions(camera, grid).reshape(-1, 3)
    n = len(vec)
    geomid = np.zeros(n, dtype=np.int32)
    dist = np.zeros(n, dtype=np.float64)
    mujoco.mj_multiRay(model, data, camera.position.astype(np.float64), vec.ravel(), None, 1, bodyexclude,
                       geomid, dist, None, n, 1e9)
    dist = np.where(geomid >= 0, dist, np.nan)  # the direction's z is 1, so the ray parameter is the depth
    return dist.reshape(len(grid.rows), len(grid.cols))


def collider_depth_reference(model: mujoco.MjModel, data: mujoco.MjData, camera: Camera, grid: PixelGrid, *,
                             bodyexclude: int = -1) -> np.ndarray:
    """Plain version of `collider_depth`: one `mj_ray` per pixel with a unit direction, converted to depth."""
    dirs = ray_directions(camera, grid)
    out = np.full(dirs.shape[:2], np.nan)
    geomid = np.zeros(1, dtype=np.int32)
    pnt = camera.position.astype(np.float64)
    for i in range(dirs.shape[0]):
        for j in range(dirs.shape[1]):
            length = float(np.linalg.norm(dirs[i, j]))
            d = mujoco.mj_ray(model, data, pnt, dirs[i, j] / length, None, 1, bodyexclude, geomid)
            if d >= 0:
                out[i, j] = d / length
    return out


@dataclass(frozen=True)
class Alignment:
    """median_abs_diff: m over the compared pixels (NaN when none); compared: how many pixels."""

    median_abs_diff: float
    compared: int
    sampled: int


def compare_depth(splat_depth: np.ndarray, splat_alpha: np.ndarray, grid: PixelGrid, colliders: np.ndarray, *,
                  min_alpha: float = 0.5) -> Alignment:
    """Median |splat depth - collider depth| over grid pixels with alpha >= min_alpha and a collider hit.

    splat_depth, splat_alpha: [H, W] from the renderer; colliders: [R, C] from collider_depth.
    """
    ix = np.ix_(grid.rows, grid.cols)
    depth, alpha = np.asarray(splat_depth, np.float64)[ix], np.asarray(splat_alpha)[ix]
    use = (alpha >= min_alpha) & np.isfinite(colliders) & (depth > 0)
    diff = np.abs(depth[use] - colliders[use])
    return Alignment(median_abs_diff=float(np.median(diff)) if diff.size else float("nan"),
                     compared=int(use.sum()), sampled=int(colliders.size))


def min_compared(sampled: int, fraction: float) -> int:
    """The fewest compared pixels that make a frame's median meaningful: `fraction` of those sampled, at least 1."""
    return max(1, math.ceil(fraction * sampled))


def frame_problem(a: Alignment, *, tolerance: float, min_fraction: float) -> str | None:
    """Why a frame fails the alignment check (too few pixels compared, or depths too far apart), else None."""
    need = min_compared(a.sampled, min_fraction)
    if a.compared < need:
        return (f"{a.compared} of {a.sampled} sampled pixels compared, fewer than the minimum {need} "
                f"({min_fraction:g} of them): nothing to align with")
    if a.median_abs_diff > tolerance:
        return f"median depth difference {a.median_abs_diff:.3f} m > {tolerance} m"
    return None
