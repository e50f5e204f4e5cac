"""Navigation-grade colliders: boxes covering a voxelisation of the mesh, each trimmed to the mesh inside it.

The mesh is voxelised at `pitch` (every cell its surface crosses, plus the space it encloses; holes smaller
than a cell are sealed by this), the solid cells are covered greedily by boxes, and each box face that
borders only empty space is pulled in to the mesh's extreme inside the box. Axis-aligned surfaces come out
exact or within half a cell (beside a corner), slanted or curved ones as steps of at most one cell. No mesh is too open, too broken or too
detailed for it, and it takes about a second where CoACD can take minutes.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from sagebench.collider_export.convex import ConvexPart, hull_part
from sagebench.collider_export.quality import lattice_points

OFF_BAND = 0.02  # weight of empty space above or below the agent band when boxes are merged


def voxel_parts(vertices: np.ndarray, faces: np.ndarray, *, pitch: float, max_parts: int,
                band: tuple[float, float] | None = None) -> list[ConvexPart]:
    """Box parts for a mesh (vertices [V, 3] m, faces [F, 3]); at most max_parts of them (boxes merged where
    the greedy cover needs more, cheapest first: empty space outside the agent `band` (z range) costs little)."""
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces, dtype=np.int64)]
    points = lattice_points(tri, pitch / 2)
    lo = points.min(axis=0) - pitch / 2
    cell = np.floor((points - lo) / pitch).astype(np.int64)
    shape = cell.max(axis=0) + 1
    solid = np.zeros(shape, dtype=bool)
    solid[cell[:, 0], cell[:, 1], cell[:, 2]] = True
    solid = ndimage.binary_fill_holes(solid)
    z = lo[2] + (np.arange(shape[2]) + 0.5) * pitch
    boxes = merge_boxes(greedy_boxes(solid), max_parts, layer_weights(z, band))
    return [_trimmed(b, solid, points, cell, lo, pitch) for b in boxes]


def greedy_boxes(solid: np.ndarray) -> list[tuple[int, int, int, int, int, int]]:
    """Disjoint boxes (i0, j0, k0, i1, j1, k1), half-open cell ranges, that exactly cover the True cells of
    `solid` [X, Y, Z]: from the first free cell grow along z, then y, then x while the slab stays solid."""
    free = solid.copy()
    boxes = []
    for i, j, k in np.argwhere(solid):
        if not free[i, j, k]:
            continue
        k1 = k + 1
        while k1 < free.shape[2] and free[i, j, k1]:
            k1 += 1
        j1 = j + 1
        while j1 < free.shape[1] and free[i, j1, k:k1].all():
            j1 += 1
        i1 = i + 1
        while i1 < free.shape[0] and free[i1, j:j1, k:k1].all():
            i1 += 1
        free[i:i1, j:j1, k:k1] = False
        boxes.append((int(i), int(j), int(k), i1, j1, k1))
    return boxes


def layer_weights(z: np.ndarray, band: tuple[float, float] | None) -> np.ndarray:
    """[Z] weight of a cell per layer (centres z, m): 1 inside the band, OFF_BAND outside it (all 1 without a band)."""
    if band is None:
        return np.ones(len(z))
    return np.where((z >= band[0]) & (z <= band[1]), 1.0, OFF_BAND)


def merge_boxes(boxes: list[tuple[int, ...]], max_parts: int, weights: np.ndarray) -> list[tuple[int, ...]]:
    """Merge pairs into their bounding box until at most max_parts, first the pair whose merged box adds the
    least weighted volume (cells weighted per z layer by `weights` [Z]; overlaps aside)."""
    b = np.array(boxes, dtype=np.float64).reshape(-1, 6)
    cum = np.concatenate([[0.0], np.cumsum(weights)])

    def wvol(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        return (hi[..., 0] - lo[..., 0]) * (hi[..., 1] - lo[..., 1]) * (cum[hi[..., 2].astype(int)] - cum[lo[..., 2].astype(int)])

    while len(b) > max_parts:
        lo = np.minimum(b[:, None, :3], b[None, :, :3])
        hi = np.maximum(b[:, None, 3:], b[None, :, 3:])
        own = wvol(b[:, :3], b[:, 3:])
        cost = wvol(lo, hi) - own[:, None] - own[None, :]
        np.fill_diagonal(cost, np.inf)
        i, j = np.unravel_index(np.argmin(cost), cost.shape)
        merged = np.concatenate([lo[i, j], hi[i, j]])
        b = np.vstack([np.delete(b, [i, j], axis=0), merged])
    return [tuple(int(x) for x in row) for row in b]


def _trimmed(box: tuple[int, ...], solid: np.ndarray, points: np.ndarray, cell: np.ndarray, lo: np.ndarray,
             pitch: float) -> ConvexPart:
    """The box in metres, each face that borders only empty cells pulled in to the mesh points inside the box."""
    i0, j0, k0, i1, j1, k1 = box
    start, stop = np.array([i0, j0, k0]), np.array([i1, j1, k1])
    bmin, bmax = lo + start * pitch, lo + stop * pitch
    inside = np.all((cell >= start) & (cell < stop), axis=1)
    if inside.any():
        pmin, pmax = points[inside].min(axis=0), points[inside].max(axis=0)
        for axis in range(3):
            if _open_side(solid, start, stop, axis, low=True):
                bmin[axis] = max(bmin[axis], pmin[axis])
            if _open_side(solid, start, stop, axis, low=False):
                bmax[axis] = min(bmax[axis], pmax[axis])
    corners = np.array([[x, y, z] for x in (bmin[0], bmax[0]) for y in (bmin[1], bmax[1]) for z in (bmin[2], bmax[2])])
    return hull_part(corners)


def _open_side(solid: np.ndarray, start: np.ndarray, stop: np.ndarray, axis: int, *, low: bool) -> bool:
    """No solid cell touches the box's face on this side (the layer just beyond it is empty or off the grid)."""
    layer = start[axis] - 1 if low else stop[axis]
    if layer < 0 or layer >= solid.shape[axis]:
        return True
    index = [slice(s, e) for s, e in zip(start, stop)]
    index[axis] = slice(layer, layer + 1)
    return not solid[tuple(index)].any()
