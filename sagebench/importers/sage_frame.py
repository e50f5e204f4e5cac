"""Where SAGE-3D's 3D frame of an InteriorGS scene lies: the offset its rounded map bounds put into every point.

SAGE-3D's semantic_map_builder.py draws its 2D map as the dataset's grid turned by 180 degrees (a world point w is
2 * min + size * scale - w there, per axis) and writes each mask cell's centre rounded to 2 decimals (format2): the
cells of every label's box footprint, of occupancy.png's wall value (its commonest value between 0 and 250) and of
its 0-valued clusters of 5 cells or more (8-connected, "unable areas"). trajectory_2d_to_3d.py, and its evaluator
backwards, move a 2D point p into the 3D frame as p - (lo + hi), lo and hi the least and greatest of those rounded
centres. So a world point w is `offset` - w in the 3D frame, offset = 2 * min + size * scale - (lo + hi): the exact
sum less the rounded one (within 1 cm) when the cells reach the map's edges, as walls and outside usually do.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np
import shapely

from sagebench.importers.interiorgs_files import Label, OccupancyMap

UNABLE_MIN_CELLS = 5  # semantic_map_builder.py's least "unable area" cluster
WALL_BELOW = 250  # its wall value is the commonest pixel value in (0, WALL_BELOW)


def sage_map_cells(occupancy: OccupancyMap, labels: Sequence[Label]) -> np.ndarray:
    """[H, W] bool in sagebench's orientation: the cells SAGE-3D's semantic map gives a mask coordinate."""
    values = occupancy.values
    pixels, counts = np.unique(values, return_counts=True)
    walls = (pixels > 0) & (pixels < WALL_BELOW)
    wall_value = pixels[walls][np.argmax(counts[walls])] if walls.any() else pixels[0]
    cells = values == wall_value
    n, labelled, stats, _ = cv2.connectedComponentsWithStats((values == 0).astype(np.uint8), connectivity=8)
    big = np.flatnonzero(stats[:, cv2.CC_STAT_AREA] >= UNABLE_MIN_CELLS)
    cells |= np.isin(labelled, big[big > 0]) & (values == 0)
    for label in labels:
        cells[_footprint_cells(label.corners[:4, :2], occupancy)] = True
    return cells


def _footprint_cells(xy: np.ndarray, occupancy: OccupancyMap) -> tuple[np.ndarray, np.ndarray]:
    """(rows, columns) of the cells within a box's pixel range (clipped to the map) whose centre the footprint
    polygon covers."""
    h, w = occupancy.values.shape
    origin, s = np.asarray(occupancy.origin, dtype=np.float64), occupancy.scale
    top = np.array([w - 1, h - 1])
    lo = np.clip(np.floor((xy.min(axis=0) - origin) / s), 0, top).astype(np.int64)
    hi = np.clip(np.floor((xy.max(axis=0) - origin) / s), 0, top).astype(np.int64)
    jj, ii = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
    inside = shapely.intersects_xy(shapely.Polygon(xy), origin[0] + (jj + 0.5) * s, origin[1] + (ii + 0.5) * s)
    return ii[inside], jj[inside]


def sage_offset(occupancy: OccupancyMap, labels: Sequence[Label]) -> tuple[float, float]:
    """(ox, oy), m: a world point (x, y) is (ox - x, oy - y) in SAGE-3D's 3D frame of the scene; (0, 0) when its
    map has no mask cell (SAGE's tools have no bounds then)."""
    cells = sage_map_cells(occupancy, labels)
    if not cells.any():
        return 0.0, 0.0
    out = []
    for axis, used in enumerate((cells.any(axis=0), cells.any(axis=1))):  # x: columns, y: rows
        size, start, s = len(used), occupancy.origin[axis], occupancy.scale
        k = np.flatnonzero(used)
        lo, hi = size - 1 - int(k[-1]), size - 1 - int(k[0])  # the turned map's least and greatest index
        rounded = sum(float(f"{start + (i + 0.5) * s:.2f}") for i in (lo, hi))  # format2
        out.append(2 * start + size * s - rounded)
    return out[0], out[1]
