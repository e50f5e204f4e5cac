"""Grid geometry and rasterisers: which cells a polygon covers, touches, or a triangle lies over.

Convention (README.md, Conventions): `origin` is the world (x, y) of the lower-left corner of cell (0, 0), cells are
`resolution` metres square, and arrays are indexed [row, col] = [y, x].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from sagebench.errors import ConfigError

_EPS = 1e-9  # metres: closed tests count a shape that only touches a cell's border as touching it
MAX_GRID_CELLS = 25_000_000  # cells of one map (5000 x 5000: 250 m square at 0.05 m); ~30 bytes each while built
_CHUNK = 1 << 18  # (shape, cell) pairs tested per numpy batch, bounds memory on big scenes


@dataclass(frozen=True)
class Grid:
    origin: tuple[float, float]  # world (x, y) of the lower-left corner of cell (0, 0), m
    resolution: float  # m per cell side
    shape: tuple[int, int]  # (H rows along y, W cols along x)

    @classmethod
    def covering(cls, lo: np.ndarray, hi: np.ndarray, resolution: float, margin: float) -> Grid:
        """The grid with origin on a multiple of `resolution` that covers [lo, hi] (xy, m) plus `margin`.

        A grid of more than MAX_GRID_CELLS cells is a ConfigError naming the count, raised before any allocation.
        """
        ox = math.floor((float(lo[0]) - margin) / resolution) * resolution
        oy = math.floor((float(lo[1]) - margin) / resolution) * resolution
        w = math.ceil((float(hi[0]) + margin - ox) / resolution)
        h = math.ceil((float(hi[1]) + margin - oy) / resolution)
        if w * h > MAX_GRID_CELLS:
            raise ConfigError(f"a {w} x {h} map at {resolution:g} m is {w * h:,} cells, over the budget of "
                              f"{MAX_GRID_CELLS:,}: choose a coarser resolution", field="resolution")
        return cls((round(ox, 9), round(oy, 9)), resolution, (h, w))

    def centres(self) -> tuple[np.ndarray, np.ndarray]:
        """x [W] and y [H] of the cell centres, m."""
        h, w = self.shape
        return (
            self.origin[0] + (np.arange(w) + 0.5) * self.resolution,
            self.origin[1] + (np.arange(h) + 0.5) * self.resolution,
        )

    def cell_area(self) -> float:
        return self.resolution * self.resolution


def polygon_mask(geom: BaseGeometry, grid: Grid, *, touch: bool = False) -> np.ndarray:
    """[H, W] bool: cells whose centre lies in `geom` (closed), or with `touch` every cell it intersects."""
    h, w = grid.shape
    out = np.zeros((h, w), dtype=bool)
    if geom.is_empty:
        return out
    bounds = np.asarray(geom.bounds, dtype=np.float64)
    r0, r1, c0, c1 = (int(v[0]) for v in _windows(bounds[None, :2], bounds[None, 2:], grid, centres=False))
    if r0 > r1 or c0 > c1:
        return out
    res, (ox, oy) = grid.resolution, grid.origin
    cols, rows = np.meshgrid(np.arange(c0, c1 + 1), np.arange(r0, r1 + 1))
    shapely.prepare(geom)
    if touch:
        x0, y0 = ox + cols * res, oy + rows * res
        hit = shapely.intersects(geom, shapely.box(x0, y0, x0 + res, y0 + res))
    else:
        hit = shapely.intersects_xy(geom, ox + (cols + 0.5) * res, oy + (rows + 0.5) * res)
    out[r0 : r1 + 1, c0 : c1 + 1] = hit
    return out


def _windows(lo: np.ndarray, hi: np.ndarray, grid: Grid, *, centres: bool) -> tuple[np.ndarray, ...]:
    """Per shape, inclusive row/col ranges [N] of the cells that touch its xy box [lo, hi] ([N, 2], m),
    or with `centres` of the cells whose centre lies in it; clipped to the grid (empty when r0 > r1)."""
    res, (ox, oy), (h, w) = grid.resolution, grid.origin, grid.shape
    # cell c spans [c, c + 1] * res; its centre is at (c + 0.5) * res
    lo_off, hi_off = (-0.5, -0.5) if centres else (-1.0, 0.0)
    c0 = np.ceil((lo[:, 0] - ox - _EPS) / res + lo_off)
    r0 = np.ceil((lo[:, 1] - oy - _EPS) / res + lo_off)
    c1 = np.floor((hi[:, 0] - ox + _EPS) / res + hi_off)
    r1 = np.floor((hi[:, 1] - oy + _EPS) / res + hi_off)
    return (
        np.clip(r0, 0, h).astype(np.int64),
        np.clip(r1, -1, h - 1).astype(np.int64),
        np.clip(c0, 0, w).astype(np.int64),
        np.clip(c1, -1, w - 1).astype(np.int64),
    )


def _pairs(r0: np.ndarray, r1: np.ndarray, c0: np.ndarray, c1: np.ndarray) -> tuple[np.ndarray, ...]:
    """Every (shape, row, col) in each shape's window, flattened: shape index [P], row [P], col [P]."""
    nr = np.maximum(r1 - r0 + 1, 0)
    nc = np.maximum(c1 - c0 + 1, 0)
    n = nr * nc
    idx = np.repeat(np.arange(len(n)), n)
    local = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
    return idx, r0[idx] + local // nc[idx], c0[idx] + local % nc[idx]


def touched_cells(polys: np.ndarray, grid: Grid) -> tuple[np.ndarray, np.ndarray]:
    """Rows and cols of every cell that a convex polygon touches (closed test, separating axes).

    polys: [N, K, 2] float, convex polygons with vertices in cyclic order, m; repeat a vertex to pad
    (a polygon may be a segment or a point: a vertical triangle seen from above is a segment).
    Returns row [P], col [P] int64, possibly with repeats.
    """
    if len(polys) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    res, (ox, oy) = grid.resolution, grid.origin
    edges = np.roll(polys, -1, axis=1) - polys  # [N, K, 2]
    normals = np.stack([-edges[..., 1], edges[..., 0]], axis=-1)  # [N, K, 2], unnormalised
    proj = np.einsum("nkd,njd->nkj", normals, polys)  # [N, K axes, K vertices]
    pmin, pmax = proj.min(axis=2), proj.max(axis=2)  # [N, K]
    reach = 0.5 * res * np.abs(normals).sum(axis=2)  # [N, K] half-width of a cell on each axis
    tol = 1e-7 * res * np.linalg.norm(normals, axis=2) + _EPS
    r0, r1, c0, c1 = _windows(polys.min(axis=1), polys.max(axis=1), grid, centres=False)
    idx, rows, cols = _pairs(r0, r1, c0, c1)
    keep = np.zeros(len(idx), dtype=bool)
    for s in range(0, len(idx), _CHUNK):
        i, r, c = idx[s : s + _CHUNK], rows[s : s + _CHUNK], cols[s : s + _CHUNK]
        cx, cy = ox + (c + 0.5) * res, oy + (r + 0.5) * res
        centre = normals[i, :, 0] * cx[:, None] + normals[i, :, 1] * cy[:, None]  # [B, K]
        apart = (pmax[i] < centre - reach[i] - tol[i]) | (pmin[i] > centre + reach[i] + tol[i])
        keep[s : s + _CHUNK] = ~apart.any(axis=1)
    return rows[keep], cols[keep]


def touched_cells_reference(polys: np.ndarray, grid: Grid) -> tuple[np.ndarray, np.ndarray]:
    """Plain version of `touched_cells` with shapely: the convex hull of each polygon against every cell box."""
    rows, cols = [], []
    for poly in polys:
        hull = shapely.MultiPoint(poly).convex_hull
        mask = polygon_mask(hull, grid, touch=True)
        r, c = np.nonzero(mask)
        rows.append(r)
        cols.append(c)
    return np.concatenate(rows).astype(np.int64), np.concatenate(cols).astype(np.int64)


def triangle_centre_hits(tris: np.ndarray, grid: Grid) -> tuple[np.ndarray, ...]:
    """Where each triangle lies over a cell centre, and its height there.

    tris: [N, 3, 3] float, world m. Triangles seen edge-on from above (vertical) are skipped.
    Returns triangle index [P], row [P], col [P] (int64) and z [P] (float64, m) for every cell centre
    inside a triangle's xy projection (closed test; a centre on a shared edge counts for both triangles).
    """
    xy = tris[:, :, :2]
    a, b, c = xy[:, 0], xy[:, 1], xy[:, 2]
    area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    flat = np.abs(area2) > 1e-12
    src = np.nonzero(flat)[0]
    r0, r1, c0, c1 = _windows(xy[src].min(axis=1), xy[src].max(axis=1), grid, centres=True)
    idx, rows, cols = _pairs(r0, r1, c0, c1)
    res, (ox, oy) = grid.resolution, grid.origin
    out_i, out_r, out_c, out_z = [], [], [], []
    for s in range(0, len(idx), _CHUNK):
        j, r, col = src[idx[s : s + _CHUNK]], rows[s : s + _CHUNK], cols[s : s + _CHUNK]
        px, py = ox + (col + 0.5) * res, oy + (r + 0.5) * res
        ta, tb, tc = tris[j, 0], tris[j, 1], tris[j, 2]
        w_a = ((tb[:, 0] - px) * (tc[:, 1] - py) - (tb[:, 1] - py) * (tc[:, 0] - px)) / area2[j]
        w_b = ((tc[:, 0] - px) * (ta[:, 1] - py) - (tc[:, 1] - py) * (ta[:, 0] - px)) / area2[j]
        w_c = 1.0 - w_a - w_b
        inside = (w_a >= -1e-9) & (w_b >= -1e-9) & (w_c >= -1e-9)
        z = w_a * ta[:, 2] + w_b * tb[:, 2] + w_c * tc[:, 2]
        out_i.append(j[inside])
        out_r.append(r[inside])
        out_c.append(col[inside])
        out_z.append(z[inside])
    if not out_i:
        empty = np.zeros(0, np.int64)
        return empty, empty, empty, np.zeros(0)
    return np.concatenate(out_i), np.concatenate(out_r), np.concatenate(out_c), np.concatenate(out_z)


def triangle_centre_hits_reference(tris: np.ndarray, grid: Grid) -> tuple[np.ndarray, ...]:
    """Plain version of `triangle_centre_hits`: every triangle against every cell centre, one at a time."""
    xs, ys = grid.centres()
    hits = []
    for j, t in enumerate(tris):
        (ax, ay, az), (bx, by, bz), (cx, cy, cz) = t
        area2 = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        if abs(area2) <= 1e-12:
            continue
        for r, py in enumerate(ys):
            for c, px in enumerate(xs):
                wa = ((bx - px) * (cy - py) - (by - py) * (cx - px)) / area2
                wb = ((cx - px) * (ay - py) - (cy - py) * (ax - px)) / area2
                wc = 1.0 - wa - wb
                if min(wa, wb, wc) >= -1e-9:
                    hits.append((j, r, c, wa * az + wb * bz + wc * cz))
    if not hits:
        empty = np.zeros(0, np.int64)
        return empty, empty, empty, np.zeros(0)
    arr = np.array(hits)
    return arr[:, 0].astype(np.int64), arr[:, 1].astype(np.int64), arr[:, 2].astype(np.int64), arr[:, 3]
