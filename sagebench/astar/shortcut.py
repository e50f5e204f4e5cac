"""Grid path to waypoints: line-of-sight shortcutting on `navigable`, world coordinates and a yaw per waypoint.

A shortcut segment joins two cell centres. It is kept only if every cell its supercover touches is
navigable at its centre (1), where the supercover is every cell whose closed square the segment meets, both side
cells included when it passes exactly through a grid corner. So a waypoint path never crosses, nor
grazes the corner of, a non-navigable cell. A narrow passage's cells (topdown/passages.py: 2) stay waypoints,
each at its anchor, joined to the path by single grid steps.
"""

from __future__ import annotations

from collections.abc import Mapping

import numba
import numpy as np


@numba.njit(cache=True)
def supercover(r0: int, c0: int, r1: int, c1: int) -> np.ndarray:
    """[K, 2] int64 (row, col) of every cell the segment between the two cell centres touches, in order."""
    nx, ny = abs(c1 - c0), abs(r1 - r0)
    sx = 1 if c1 > c0 else -1
    sy = 1 if r1 > r0 else -1
    out = np.empty((2 * (nx + ny) + 1, 2), dtype=np.int64)
    r, c = r0, c0
    out[0, 0], out[0, 1] = r, c
    k = 1
    ix = iy = 0
    while ix < nx or iy < ny:
        # compare the parameters of the next vertical and horizontal boundary crossings, exactly
        decision = (1 + 2 * ix) * ny - (1 + 2 * iy) * nx
        if decision == 0:  # through a corner: both side cells touch the segment
            out[k, 0], out[k, 1] = r, c + sx
            out[k + 1, 0], out[k + 1, 1] = r + sy, c
            k += 2
            c += sx
            r += sy
            ix += 1
            iy += 1
        elif decision < 0:
            c += sx
            ix += 1
        else:
            r += sy
            iy += 1
        out[k, 0], out[k, 1] = r, c
        k += 1
    return out[:k]


@numba.njit(cache=True)
def segment_clear(nav: np.ndarray, r0: int, c0: int, r1: int, c1: int) -> bool:
    """True when every cell of the segment's supercover is navigable at its centre (nav: [H, W] uint8, 1; a
    passage cell, 2, is stood in at its anchor only, so no shortcut crosses or starts at one)."""
    cells = supercover(r0, c0, r1, c1)
    for i in range(cells.shape[0]):
        if nav[cells[i, 0], cells[i, 1]] != 1:
            return False
    return True


@numba.njit(cache=True)
def shortcut_indices(nav: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Indices into `cells` [K, 2] of the kept waypoints (first and last always kept).

    Greedy: from the current waypoint, extend the segment along the grid path while it stays clear;
    the last clear cell becomes the next waypoint. Then drop every waypoint whose neighbours see each
    other, until none can go. Every kept segment passes `segment_clear`.
    """
    n = cells.shape[0]
    keep = np.empty(n, dtype=np.int64)
    keep[0] = 0
    m = 1
    anchor = 0
    j = 1
    while j < n:
        if j == anchor + 1 or segment_clear(nav, cells[anchor, 0], cells[anchor, 1], cells[j, 0], cells[j, 1]):
            j += 1
            continue
        anchor = j - 1
        keep[m] = anchor
        m += 1
    if n > 1:
        keep[m] = n - 1
        m += 1
    changed = True
    while changed:
        changed = False
        k = 1
        while k < m - 1:
            a, b = keep[k - 1], keep[k + 1]
            if segment_clear(nav, cells[a, 0], cells[a, 1], cells[b, 0], cells[b, 1]):
                keep[k:m - 1] = keep[k + 1:m]
                m -= 1
                changed = True
            else:
                k += 1
    return keep[:m]


def waypoints(
    cells: np.ndarray,  # [K, 2] int (row, col) waypoint cells
    resolution: float,  # metres per cell
    origin: tuple[float, float],  # world (x, y) of the lower-left corner of cell (0, 0)
    z: float,  # floor height, m
    anchors: Mapping[tuple[int, int], tuple[float, float]] | None = None,  # passage cell -> world (x, y)
) -> np.ndarray:
    """[K, 4] float64 waypoints (x, y, z, yaw): cell centres in world metres (a passage cell's anchor instead),
    yaw = heading of the next segment.

    The last waypoint keeps the heading of the segment that reaches it (0 for a single-cell path).
    """
    out = np.empty((len(cells), 4), dtype=np.float64)
    for k, (r, c) in enumerate(np.asarray(cells, dtype=np.int64)):
        out[k, :2] = (anchors or {}).get((int(r), int(c)), (origin[0] + (c + 0.5) * resolution,
                                                              origin[1] + (r + 0.5) * resolution))
    out[:, 2] = z
    if len(cells) == 1:
        out[0, 3] = 0.0
        return out
    d = np.diff(out[:, :2], axis=0)
    yaw = np.arctan2(d[:, 1], d[:, 0])
    out[:-1, 3] = yaw
    out[-1, 3] = yaw[-1]
    return out


def polyline_length(points: np.ndarray) -> float:
    """Length in metres of an [K, >=2] polyline in the XY plane."""
    d = np.diff(np.asarray(points)[:, :2], axis=0)
    return float(np.hypot(d[:, 0], d[:, 1]).sum())
