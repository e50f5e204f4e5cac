"""Coverage of a no-goal (exploration) episode, measured on the scene's own navigable map.

coverage = |main-region navigable cells whose centre lies within `radius` of the executed path| / |main-region
navigable cells|. The path is the polyline through the poses (every segment counts, not only the poses), the main
region is build-scene's (the largest connected navigable region: the floor an agent starting in it can reach), and
the radius is the agent's own (the floor its body passed over). The denominator is the scene's, never a constant:
SAGE-Bench divides its visited 0.5 m cells by 400 whatever the scene, so the same walk scores the same in a studio
and in a mansion; here a scene twice as large halves the coverage of the same path.
"""

from __future__ import annotations

import numpy as np

from sagebench.topdown.regions import label_regions


def main_region(navigable: np.ndarray) -> np.ndarray:
    """[H, W] bool: the main region of a navigable map (nonzero = navigable), the largest 4-connected region,
    the lowest-numbered among equals, as build-scene numbers them (`topdown.regions`); all False without one."""
    labels, count = label_regions(np.asarray(navigable) != 0)
    if not count:
        return np.zeros(labels.shape, dtype=bool)
    return labels == int(np.argmax(np.bincount(labels.ravel())[1:])) + 1


def swept_cells(xy: np.ndarray, shape: tuple[int, int], resolution: float, origin: tuple[float, float],
                radius: float) -> np.ndarray:
    """[H, W] bool: the cells of a grid (`shape`, `resolution` m/cell, `origin` the world (x, y) of cell (0, 0)'s
    lower-left corner) whose centre lies within `radius` m of the polyline through the points xy [T, >=2]."""
    pts = np.atleast_2d(np.asarray(xy, dtype=np.float64))[:, :2]
    out = np.zeros(shape, dtype=bool)
    if not len(pts):
        return out
    keep = np.concatenate([[True], np.any(np.diff(pts, axis=0) != 0, axis=1)])  # a step in place adds nothing
    pts = pts[keep]
    starts, ends = pts if len(pts) == 1 else pts[:-1], pts if len(pts) == 1 else pts[1:]
    o = np.asarray(origin, dtype=np.float64)
    h, w = shape
    for a, b in zip(starts, ends):
        lo = np.floor((np.minimum(a, b) - radius - o) / resolution).astype(np.int64)
        hi = np.ceil((np.maximum(a, b) + radius - o) / resolution).astype(np.int64)
        c0, r0 = np.maximum(lo, 0)
        c1, r1 = min(hi[0], w), min(hi[1], h)
        if c0 >= c1 or r0 >= r1:
            continue
        cx = (np.arange(c0, c1) + 0.5) * resolution + o[0]
        cy = (np.arange(r0, r1) + 0.5) * resolution + o[1]
        out[r0:r1, c0:c1] |= _segment_distance(cx[None, :], cy[:, None], a, b) <= radius
    return out


def _segment_distance(x: np.ndarray, y: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from the points (x, y) (broadcast together) to the segment a-b."""
    ab = b - a
    denom = float(ab @ ab)
    t = 0.0 if denom == 0.0 else np.clip(((x - a[0]) * ab[0] + (y - a[1]) * ab[1]) / denom, 0.0, 1.0)
    return np.hypot(x - (a[0] + t * ab[0]), y - (a[1] + t * ab[1]))


def coverage(xy: np.ndarray, region: np.ndarray, resolution: float, origin: tuple[float, float],
             radius: float) -> float:
    """The share of `region`'s cells ([H, W] bool, the main region) within `radius` of the path xy [T, >=2]
    (module docstring); 0 for an empty region."""
    region = np.asarray(region, dtype=bool)
    total = int(region.sum())
    if not total:
        return 0.0
    swept = swept_cells(xy, region.shape, resolution, origin, radius)
    return float((swept & region).sum() / total)
