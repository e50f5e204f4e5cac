"""Navigation-grade colliders: the convex hulls of a voxelisation's box cover, each of the mesh inside its box.

The mesh is voxelised at `pitch` (every cell its surface crosses, plus the space it encloses; holes smaller
than a cell are sealed by this), the solid cells are covered greedily by boxes (merged where there are more
than the part budget), and each box becomes the hull of the mesh surface points inside it (a lattice no
coarser than pitch / 2) and of its enclosed cells. So a part never reaches past the mesh's own extent in its
box: a slanted or curved surface comes out as its hull within the box, not as box steps, and merged boxes
of a plant's leaves stay near the leaves. Where the surface crosses from one box into the next, the two
hulls leave a seam of at most the lattice spacing (no source point farther than pitch / 4 from a part;
taking points from past the box instead bridged notches). No mesh is too open, too broken or too detailed for it, and it takes about a
second where CoACD can take minutes.
"""

from __future__ import annotations

import numba
import numpy as np
from scipy import ndimage

from sagebench.collider_export.convex import ConvexPart, hull_part
from sagebench.collider_export.quality import lattice_rows

OFF_BAND = 0.02  # weight of empty space above or below the agent band when boxes are merged


def voxel_parts(vertices: np.ndarray, faces: np.ndarray, *, pitch: float, max_parts: int,
                band: tuple[float, float] | None = None, tolerance: float = 0.02) -> list[ConvexPart]:
    """Convex parts for a mesh (vertices [V, 3] m, faces [F, 3]), one per box; at most max_parts of them (boxes
    merged where the greedy cover needs more: first those whose merged box stays within `tolerance` (m) of the
    agent `band`'s footprint, and among them the ones adding the least empty space, which outside the band
    (z range) costs little)."""
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces, dtype=np.int64)]
    points, rows = lattice_rows(tri, pitch / 2)
    lo = points.min(axis=0) - pitch / 2
    cell = np.floor((points - lo) / pitch).astype(np.int64)
    shape = cell.max(axis=0) + 1
    surface = np.zeros(shape, dtype=bool)
    surface[cell[:, 0], cell[:, 1], cell[:, 2]] = True
    solid = ndimage.binary_fill_holes(surface)
    weights = layer_weights(lo[2] + (np.arange(shape[2]) + 0.5) * pitch, band)
    outside = None if band is None else band_outside(solid, weights)
    boxes = merge_boxes(greedy_boxes(solid), max_parts, weights, outside, tolerance / pitch)
    label = np.full(shape, -1, dtype=np.int64)  # the box each cell's points go to (merged boxes may overlap)
    for b, (i0, j0, k0, i1, j1, k1) in enumerate(boxes):
        label[i0:i1, j0:j1, k0:k1] = b
    enclosed = np.argwhere(solid & ~surface)  # [E, 3] cells inside a closed surface that no surface point is in
    corners, corner_owner = column_corners(enclosed, label[enclosed[:, 0], enclosed[:, 1], enclosed[:, 2]])
    point_owner = label[cell[:, 0], cell[:, 1], cell[:, 2]]
    ends = run_ends(rows, point_owner)
    pts = np.concatenate([points[ends], lo + corners * pitch])
    owner = np.concatenate([point_owner[ends], corner_owner])
    order = np.argsort(owner, kind="stable")
    groups = np.split(pts[order], np.cumsum(np.bincount(owner, minlength=len(boxes)))[:-1])
    parts = [hull_part(g) for g in groups if len(g)]  # a box wholly inside later ones has no points left
    return parts


def run_ends(rows: np.ndarray, owner: np.ndarray) -> np.ndarray:
    """[N] bool: the first and last point of each run of one owner along one lattice row (rows [N], owner [N]):
    the points between lie on the segment joining them, so the owner's hull needs only these."""
    change = (rows[1:] != rows[:-1]) | (owner[1:] != owner[:-1])
    first = np.concatenate([[True], change])
    last = np.concatenate([change, [True]])
    return first | last


def column_corners(cells: np.ndarray, owner: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The cell corners [K, 3] (in cells) whose hull, per owner, is the hull of every corner of `cells` [E, 3]
    (owner [E]), and their owners [K]: per owner and (x, y) column the bottom corners of the lowest cell and the
    top corners of the highest, since every corner between them lies on the vertical segments joining those.
    (Eight corners of each of a wall's 900 k enclosed cells made its hulls take 17 s.)"""
    if not len(cells):
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    span = cells.max(axis=0) + 1
    key = (owner * span[0] + cells[:, 0]) * span[1] + cells[:, 1]  # one integer per (owner, x, y) column
    uniq, inverse = np.unique(key, return_inverse=True)
    columns = np.column_stack([uniq // (span[0] * span[1]), uniq // span[1] % span[0], uniq % span[1]])
    bottom = np.full(len(columns), np.iinfo(np.int64).max)
    top = np.full(len(columns), np.iinfo(np.int64).min)
    np.minimum.at(bottom, inverse, cells[:, 2])
    np.maximum.at(top, inverse, cells[:, 2] + 1)
    square = np.array([[0, 0], [0, 1], [1, 0], [1, 1]])
    xy = (columns[:, None, 1:] + square[None]).reshape(-1, 2)  # [C * 4, 2]
    z = np.concatenate([np.repeat(bottom, 4), np.repeat(top, 4)])
    corners = np.column_stack([np.concatenate([xy, xy]), z]).astype(np.float64)
    return corners, np.tile(np.repeat(columns[:, 0], 4), 2)


def greedy_boxes(solid: np.ndarray) -> list[tuple[int, int, int, int, int, int]]:
    """Disjoint boxes (i0, j0, k0, i1, j1, k1), half-open cell ranges, that exactly cover the True cells of
    `solid` [X, Y, Z]: from the first free cell grow along z, then y, then x while the slab stays solid."""
    return [tuple(int(x) for x in row) for row in _greedy_boxes(np.ascontiguousarray(solid, dtype=np.bool_))]


@numba.njit(cache=True)
def _greedy_boxes(solid: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled; greedy_boxes_reference checks it
    free = solid.copy()
    nx, ny, nz = solid.shape
    out = np.empty((64, 6), dtype=np.int64)
    n = 0
    for i in range(nx):
        for j in range(ny):
            for k in range(nz):
                if not free[i, j, k]:
                    continue
                k1 = k + 1
                while k1 < nz and free[i, j, k1]:
                    k1 += 1
                j1 = j + 1
                while j1 < ny and free[i, j1, k:k1].all():
                    j1 += 1
                i1 = i + 1
                while i1 < nx and free[i1, j:j1, k:k1].all():
                    i1 += 1
                free[i:i1, j:j1, k:k1] = False
                if n == len(out):
                    grown = np.empty((2 * n, 6), dtype=np.int64)
                    grown[:n] = out
                    out = grown
                out[n, 0], out[n, 1], out[n, 2], out[n, 3], out[n, 4], out[n, 5] = i, j, k, i1, j1, k1
                n += 1
    return out[:n]


def greedy_boxes_reference(solid: np.ndarray) -> list[tuple[int, int, int, int, int, int]]:
    """greedy_boxes in plain Python."""
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


def merge_boxes(boxes: list[tuple[int, ...]], max_parts: int, weights: np.ndarray,
                outside: np.ndarray | None = None, tolerance: float = 1.0) -> list[tuple[int, ...]]:
    """Merge pairs into their bounding box until at most max_parts. The pair merged first is the one whose box
    reaches least far past the band footprint beyond `tolerance` (`outside` [X, Y]: cells from each xy cell to
    the footprint, 0 on it; only boxes that reach a layer of weight 1 count), then the one that adds the least
    weighted volume (cells weighted per z layer by `weights` [Z]; overlaps aside)."""
    b = np.array(boxes, dtype=np.int64).reshape(-1, 6)
    cum = np.concatenate([[0.0], np.cumsum(weights)])
    inband = np.concatenate([[0], np.cumsum(weights >= 1.0)])
    table = None if outside is None else _max_table(outside)
    big = cum[-1] * b[:, 3:5].max(initial=1) ** 2 + 1.0  # more than any weighted volume: excess decides first

    def cost(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
        wv = (hi[..., 0] - lo[..., 0]) * (hi[..., 1] - lo[..., 1]) * (cum[hi[..., 2]] - cum[lo[..., 2]])
        if table is None:
            return wv
        reach = (inband[hi[..., 2]] - inband[lo[..., 2]]) > 0
        excess = np.where(reach, np.clip(_rect_max(table, lo[..., :2], hi[..., :2]) - tolerance, 0.0, None), 0.0)
        return excess * big + wv

    def pair_cost(i: np.ndarray, j: np.ndarray) -> np.ndarray:
        own = cost(b[:, :3], b[:, 3:])
        return cost(np.minimum(b[i, :3], b[j, :3]), np.maximum(b[i, 3:], b[j, 3:])) - own[i] - own[j]

    n = len(b)
    alive = np.ones(n, dtype=bool)
    ii, jj = np.triu_indices(n, 1)
    pairs = np.full((n, n), np.inf)  # [i, j], i < j
    pairs[ii, jj] = pair_cost(ii, jj)
    for _ in range(n - max_parts):
        i, j = np.unravel_index(np.argmin(pairs), pairs.shape)
        b[i] = np.concatenate([np.minimum(b[i, :3], b[j, :3]), np.maximum(b[i, 3:], b[j, 3:])])
        alive[j] = False
        pairs[j, :] = pairs[:, j] = np.inf
        others = np.flatnonzero(alive & (np.arange(n) != i))
        row = pair_cost(np.full(len(others), i), others)
        lower = others < i
        pairs[others[lower], i] = row[lower]
        pairs[i, others[~lower]] = row[~lower]
    return [tuple(int(x) for x in row) for row in b[alive]]


def band_outside(solid: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """[X, Y] distance in cells from each xy cell to the band footprint (the xy shadow of the solid cells in
    layers of weight 1, enclosed areas filled); 0 on the footprint, everywhere when no cell is in the band."""
    footprint = ndimage.binary_fill_holes(solid[:, :, weights >= 1.0].any(axis=2))
    if not footprint.any():
        return np.zeros(footprint.shape)
    return ndimage.distance_transform_edt(~footprint)


def _max_table(values: np.ndarray) -> np.ndarray:
    """Sparse table [A, B, X, Y]: entry [a, b, x, y] is the max of values [x:x + 2**a, y:y + 2**b] (clipped)."""
    x, y = values.shape
    la, lb = int(np.log2(x)) + 1, int(np.log2(y)) + 1
    table = np.zeros((la, lb, x, y))
    table[0, 0] = values
    for a in range(la):
        if a:
            step = 1 << (a - 1)
            table[a, 0] = table[a - 1, 0]
            table[a, 0, : x - step] = np.maximum(table[a - 1, 0, : x - step], table[a - 1, 0, step:])
        for c in range(1, lb):
            step = 1 << (c - 1)
            table[a, c] = table[a, c - 1]
            table[a, c, :, : y - step] = np.maximum(table[a, c - 1, :, : y - step], table[a, c - 1, :, step:])
    return table


def _rect_max(table: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Max of the tabled values over each half-open rectangle [lo, hi) ([..., 2] cell indices, non-empty)."""
    size = hi - lo
    a = np.log2(size[..., 0]).astype(np.int64)
    c = np.log2(size[..., 1]).astype(np.int64)
    x1, y1 = hi[..., 0] - (1 << a), hi[..., 1] - (1 << c)
    x0, y0 = lo[..., 0], lo[..., 1]
    return np.maximum(np.maximum(table[a, c, x0, y0], table[a, c, x1, y0]),
                      np.maximum(table[a, c, x0, y1], table[a, c, x1, y1]))
