"""Narrow passages judged on the exact geometry, so a room is not cut off by where the grid's cells happen to fall.

The navigable map (occupancy.inflate) is conservative twice over: a cell is blocked when geometry touches any part
of it, and the agent stands at cell centres. A doorway 1.5 cm wider than the agent then holds a navigable cell only
by luck (at 0.05 m, the band of centres the agent fits at is 1.5 cm of every 5). Where the map falls apart into
regions, the cells between them that the map left out are re-judged: each at SUB x SUB points against the exact
geometry in the band (the clipped triangles, the floor plan's edge, and the cells blocked by a solid span alone),
and where one of its points has the agent's radius of clearance it may be stood in, at that point (its anchor).
Of those cells only the shortest 4-connected chain between two regions is opened (a breadth-first search from
every region at once, regions joined in the order the search meets them), marked PASSAGE in the navigable map:
A* walks through them, paths keep each one as a waypoint at its anchor (astar.shortcut), and trajectories never
start or end on one. Steps from or to an anchor are one cell long: where they bend round a corner the agent can
come within (step / 2)^2 / (2 radius) of it (3 mm at 0.05 m), inside validate's 1 cm contact tolerance.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import shapely
from scipy import ndimage
from shapely.geometry.base import BaseGeometry

from sagebench.topdown.raster import Grid, touched_cells
from sagebench.topdown.regions import label_regions

PASSAGE = 2  # navigable value of a cell the agent fits in only off its centre, at its anchor
SUB = 5  # points per side of each search step where a left-out cell is judged
REFINE = 3  # finer search steps around the best point
MARGIN = 0.002  # m of clearance past the agent's radius an anchor needs (the replay's prism is up to 1 mm wider)
SLACK = 1e-9  # m kept in bounds that settle a cell early: far above the distances' rounding, far below a step

Clearance = Callable[[np.ndarray], np.ndarray]  # shapely points [N] -> clearance [N], m (`_clearance_field`)


@dataclass(frozen=True)
class Passages:
    cells: np.ndarray  # [K, 2] int32 (row, col) opened, in the order found
    anchors: np.ndarray  # [K, 2] float64 world (x, y) where the agent stands in each


def open_passages(navigable: np.ndarray, occupied: np.ndarray, band_polys: np.ndarray, plan: BaseGeometry,
                  grid: Grid, radius: float) -> tuple[np.ndarray, Passages]:
    """navigable [H, W] bool (occupancy.inflate's) -> [H, W] uint8 (1 navigable, PASSAGE opened here) and the
    cells opened. occupied [H, W] bool; band_polys [M, 9, 2]: the band outlines of the blocking triangles
    (occupancy.clip_to_band), world m; plan: the floor plan; radius: the agent's, m."""
    out = navigable.astype(np.uint8)
    none = Passages(np.zeros((0, 2), np.int32), np.zeros((0, 2)))
    labels, count = label_regions(navigable)
    if count < 2:
        return out, none
    res = grid.resolution
    reach = ndimage.distance_transform_edt(~occupied) * res  # centre to the nearest blocked cell's centre
    candidates = ~occupied & ~navigable & (reach + res * np.sqrt(2) >= radius)
    rc = np.argwhere(candidates)
    if not len(rc):
        return out, none
    clearance = _clearance_field(occupied, band_polys, plan, grid)
    fits = np.zeros(navigable.shape, dtype=bool)
    fits[rc[:, 0], rc[:, 1]] = _fitting(rc, clearance, grid, need=radius + MARGIN)
    chain = _bridges(labels, fits)
    if not chain:
        return out, none
    cells = np.array(chain, dtype=np.int32)
    out[cells[:, 0], cells[:, 1]] = PASSAGE
    return out, Passages(cells, _best_points(cells, clearance, grid)[0])


def _fitting(rc: np.ndarray, clearance: Clearance, grid: Grid, need: float) -> np.ndarray:
    """[N] bool: whether `_best_points` finds `need` m of clearance in each cell [N, 2] (row, col), searching
    only as far as it takes to know: the cell's centre (the first step's middle point) settles a cell that clears
    `need` there or cannot reach it anywhere in the cell (`_best_points` on settling)."""
    half = grid.resolution / 2
    centre = _corners(rc, grid) + half
    at_centre = clearance(shapely.points(centre[:, 0], centre[:, 1]))
    fits = at_centre >= need
    open_ = ~fits & (np.maximum(at_centre, 0.0) + half * np.sqrt(2) >= need - SLACK)
    fits[open_] = _best_points(rc[open_], clearance, grid, need=need)[1] >= need
    return fits


def _best_points(rc: np.ndarray, clearance: Clearance, grid: Grid,
                 need: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """For each cell [N, 2] (row, col): the point of most clearance from the exact geometry (world xy [N, 2])
    and that clearance [N], m. Searched on SUB x SUB points, then REFINE times on SUB x SUB points around the
    best one at a fifth of the spacing (kept inside the cell), so an anchor in a gap lies on its middle line to
    within a fraction of a millimetre (first point in row-major order on ties). Each cell's search is its own.

    With `need` (m), a cell's search stops once it is settled whether its best clears `need`: the best only
    grows, every later point lies within `half` of the best point on each axis, and clearance changes at most
    1:1 with position (distances do; a point outside the plan has less than any inside), so a cell whose best
    plus half x sqrt(2) falls short of `need` never reaches it. Its point and clearance are then where it
    stopped; the decision best >= need is the full search's."""
    res = grid.resolution
    lo = _corners(rc, grid)
    best_xy, best = lo + res / 2, np.full(len(rc), -np.inf)
    half = res / 2
    steps = (np.arange(SUB) + 0.5) / SUB * 2 - 1  # [SUB] in (-1, 1)
    dx, dy = (d.ravel()[None] for d in np.meshgrid(steps, steps, indexing="xy"))
    on = np.arange(len(rc))  # the cells still searched
    for _ in range(REFINE + 1):
        x = np.clip(best_xy[on, 0, None] + dx * half, lo[on, 0, None], lo[on, 0, None] + res)
        y = np.clip(best_xy[on, 1, None] + dy * half, lo[on, 1, None], lo[on, 1, None] + res)
        found = clearance(shapely.points(x.ravel(), y.ravel())).reshape(x.shape)
        rows, k = np.arange(len(on)), np.argmax(found, axis=1)
        better = found[rows, k] > best[on]
        best_xy[on] = np.where(better[:, None], np.column_stack([x[rows, k], y[rows, k]]), best_xy[on])
        best[on] = np.maximum(best[on], found[rows, k])
        half = half / SUB
        if need is not None:
            on = on[(best[on] < need) & (np.maximum(best[on], 0.0) + half * np.sqrt(2) >= need - SLACK)]
    return best_xy, best


def _corners(rc: np.ndarray, grid: Grid) -> np.ndarray:
    """World xy [N, 2] of the low corner of each cell [N, 2] (row, col)."""
    res = grid.resolution
    return np.column_stack([grid.origin[0] + rc[:, 1] * res, grid.origin[1] + rc[:, 0] * res])


def _clearance_field(occupied: np.ndarray, band_polys: np.ndarray, plan: BaseGeometry, grid: Grid) -> Clearance:
    """The distance [N] (m) from each of N points to the nearest geometry in the band or the floor plan's edge;
    negative outside the plan. Cells blocked only by a solid span (no clipped triangle touches them) count as
    squares. The geometry and its tree are built once, for every query."""
    res = grid.resolution
    h, w = occupied.shape
    shapes = shapely.polygons(band_polys) if len(band_polys) else np.zeros(0, dtype=object)
    touched = np.zeros(h * w, dtype=bool)
    if len(band_polys):
        r, c = touched_cells(band_polys, grid)
        touched[r * w + c] = True
    solid = np.argwhere(occupied & ~touched.reshape(h, w) & shapely.contains_xy(plan, *_centres(grid)))
    squares = shapely.box(grid.origin[0] + solid[:, 1] * res, grid.origin[1] + solid[:, 0] * res,
                          grid.origin[0] + (solid[:, 1] + 1) * res, grid.origin[1] + (solid[:, 0] + 1) * res)
    geoms = np.concatenate([shapes, np.asarray(squares, dtype=object).reshape(-1)])
    tree = shapely.STRtree(geoms) if len(geoms) else None
    edge = plan.boundary

    def clearance(pts: np.ndarray) -> np.ndarray:
        out = shapely.distance(edge, pts)
        if tree is not None:
            (idx, _near), dist = tree.query_nearest(pts, return_distance=True, all_matches=False)
            nearest = np.full(len(pts), np.inf)
            nearest[idx] = dist
            out = np.minimum(out, nearest)
        return np.where(shapely.contains_xy(plan, shapely.get_x(pts), shapely.get_y(pts)), out, -1.0)

    return clearance


def _centres(grid: Grid) -> tuple[np.ndarray, np.ndarray]:
    xs, ys = grid.centres()
    return np.meshgrid(xs, ys, indexing="xy")


def _bridges(labels: np.ndarray, fits: np.ndarray) -> list[tuple[int, int]]:
    """The cells of `fits` [H, W] bool on the shortest 4-connected chains that join the regions of `labels`
    [H, W] int32 (0: not navigable): one breadth-first search from every region cell at once (row-major order);
    where the fronts of two regions not yet joined meet, the cells back to each region are opened. Only region
    cells next to a cell of `fits` start it: regions are 4-connected components, so no other can meet a front."""
    h, w = labels.shape
    owner = labels.astype(np.int64).copy()  # the region whose front reached each cell
    parent = np.full((h, w, 2), -1, dtype=np.int64)
    joined = {int(k): int(k) for k in np.unique(labels) if k}

    def root(k: int) -> int:
        while joined[k] != k:
            k = joined[k]
        return k

    near_fits = ndimage.binary_dilation(fits, structure=ndimage.generate_binary_structure(2, 1))
    queue = deque((int(r), int(c)) for r, c in np.argwhere((labels > 0) & near_fits))
    opened: list[tuple[int, int]] = []
    while queue:
        r, c = queue.popleft()
        for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
            nr, nc = r + dr, c + dc
            if not (0 <= nr < h and 0 <= nc < w):
                continue
            if owner[nr, nc] == 0:
                if fits[nr, nc]:
                    owner[nr, nc] = owner[r, c]
                    parent[nr, nc] = (r, c)
                    queue.append((nr, nc))
            elif root(int(owner[nr, nc])) != root(int(owner[r, c])):
                joined[root(int(owner[nr, nc]))] = root(int(owner[r, c]))
                for cell in ((r, c), (nr, nc)):
                    while labels[cell] == 0 and cell not in opened:
                        opened.append(cell)
                        cell = tuple(int(v) for v in parent[cell])
    return opened
