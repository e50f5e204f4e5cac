"""Gaussians packed for culling: contiguous chunks (one object's Gaussians in one cell of space) with bounds.

A frame projects only the chunks whose bounds can reach the image. The test is conservative with respect to
the fast renderer's own per-Gaussian cull (splat_render._project): a Gaussian at camera-frame p with largest
standard deviation s is dropped there when pz <= NEAR or its centre plus its reach
3 sqrt(s^2 |J|^2 + 0.3) + 1 px lies outside the image, and |J| <= K / pz with
K = sqrt(fx^2 (1 + limx^2) + fy^2 (1 + limy^2)). Past the left edge, for example, that is implied by
fx px + (cx + e) pz + 3 s K < 0 (e = 3 sqrt(0.3) + 1 px, plus a pixel of slack), linear in p, so its largest
value over a chunk's box of centres decides for the whole chunk. A culled chunk holds no Gaussian the
renderer would have drawn, and the chunks kept stay in packed order, so a frame is the same with or without
culling.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sagebench.render.camera import Camera
from sagebench.render.gaussians import Gaussians
from sagebench.render.splat_reference import DILATION, FOV_CLAMP, NEAR

CHUNK_CELL = 1.0  # m: an object's Gaussians are split into chunks by this grid (walls and floors span rooms)
_EDGE_PX = 3.0 * math.sqrt(DILATION) + 1.0 + 1.0  # the reach's constant part, plus a pixel for rounding


@dataclass(frozen=True)
class PackedGaussians:
    """Gaussians sorted by (instance id, cell) and their C chunks.

    gaussians  the N Gaussians in packed order
    starts     [C + 1] int64  chunk c is gaussians[starts[c]:starts[c + 1]]
    lo, hi     [C, 3] float64 box of the chunk's centres, m
    max_scale  [C] float64    largest standard deviation of any Gaussian in the chunk, m
    """

    gaussians: Gaussians
    starts: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    max_scale: np.ndarray

    @property
    def chunks(self) -> int:
        return len(self.starts) - 1


def pack(g: Gaussians, cell: float = CHUNK_CELL) -> PackedGaussians:
    """Sort `g` into chunks (stable: Gaussians of one chunk keep their order) and bound each."""
    key_cells = np.floor(g.means.astype(np.float64) / cell).astype(np.int64)
    order = np.lexsort((key_cells[:, 2], key_cells[:, 1], key_cells[:, 0], g.instance_id))
    packed = g.take(order)
    keys = np.column_stack([packed.instance_id.astype(np.int64), key_cells[order]])
    change = np.flatnonzero((np.diff(keys, axis=0) != 0).any(axis=1)) + 1 if len(keys) else np.zeros(0, np.int64)
    starts = np.concatenate([[0], change, [g.count]]).astype(np.int64) if g.count else np.zeros(1, np.int64)
    means = packed.means.astype(np.float64)
    head = starts[:-1]
    lo = np.minimum.reduceat(means, head, axis=0) if len(head) else np.zeros((0, 3))
    hi = np.maximum.reduceat(means, head, axis=0) if len(head) else np.zeros((0, 3))
    smax = np.exp(packed.log_scales.astype(np.float64).max(axis=1)) if g.count else np.zeros(0)
    max_scale = np.maximum.reduceat(smax, head) if len(head) else np.zeros(0)
    return PackedGaussians(gaussians=packed, starts=starts, lo=lo, hi=hi, max_scale=max_scale)


def _box_max(w: np.ndarray, offset: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """[V, C] max over each chunk box [C, 3] of the linear functions w [V, 3] . m + offset [V]."""
    return (np.maximum(w[:, None, :] * lo[None], w[:, None, :] * hi[None]).sum(axis=2) + offset[:, None])


def visible_chunks(packed: PackedGaussians, cam: Camera) -> np.ndarray:
    """[C] bool: chunks that may hold a Gaussian the renderer draws in `cam` (module docstring)."""
    rot, t = cam.world_to_camera[:3, :3], cam.world_to_camera[:3, 3]
    fx, fy, cx, cy, w, h = cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height
    limx, limy = FOV_CLAMP * w / (2 * fx), FOV_CLAMP * h / (2 * fy)
    k = math.sqrt(fx * fx * (1 + limx * limx) + fy * fy * (1 + limy * limy))
    e = _EDGE_PX
    # each row: coefficients (on camera x, y, z) of a function that is < -3 s K wherever a Gaussian is culled
    planes = np.array([[fx, 0.0, cx + e], [-fx, 0.0, w + e - cx], [0.0, fy, cy + e], [0.0, -fy, h + e - cy]])
    world = planes @ rot  # the same functions of world coordinates
    side = _box_max(world, planes @ t, packed.lo, packed.hi) + 3.0 * packed.max_scale[None] * k
    depth = _box_max(rot[2:3], t[2:3], packed.lo, packed.hi)[0]
    return (depth > NEAR) & (side >= 0.0).all(axis=0)


def visible_index(packed: PackedGaussians, cam: Camera) -> np.ndarray:
    """[M] int64 indices into packed.gaussians of the chunks `cam` may see, in packed order."""
    keep = np.flatnonzero(visible_chunks(packed, cam))
    if not len(keep):
        return np.zeros(0, np.int64)
    a, b = packed.starts[keep], packed.starts[keep + 1]
    lengths = b - a
    return np.repeat(a - np.concatenate([[0], np.cumsum(lengths)[:-1]]), lengths) + np.arange(lengths.sum())

