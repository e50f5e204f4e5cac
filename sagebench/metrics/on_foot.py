"""Distance on foot to a goal: what success is measured by (habitat and VLN-CE use the geodesic, not the straight line).

The walk is the shortest 8-connected, no-corner-cutting path on the navigable map (the graph the A* planner uses),
found by one Dijkstra from the goal's cell, so a stop 0.9 m from a goal behind a wall is as far as the walk round it.
A point with a clear straight line to the goal over navigable cells is at its straight distance (the grid path would
overstate it by up to 8 %); a point off the navigable map (the agent's centre pressed against an obstacle) is
snapped to the nearest navigable cell within `snap_radius` (the agent radius), else it cannot reach the goal (inf).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import distance_transform_edt
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from sagebench.astar.dijkstra_reference import grid_graph
from sagebench.metrics.coverage import main_region


@dataclass(frozen=True)
class GoalField:
    """Distances on foot (m) to one goal from every cell of its map, with the lookups to use them at any point."""

    goal_xy: np.ndarray  # [2]
    cost: np.ndarray  # [H, W] m, cell centre -> goal cell along the grid; inf where unreachable
    navmap: "NavigableMap"

    @property
    def worst(self) -> float:
        """The largest distance on foot from the goal to any navigable cell it connects to (0 for a lone cell)."""
        finite = self.cost[np.isfinite(self.cost)]
        return float(finite.max()) if finite.size else 0.0

    @property
    def worst_straight(self) -> float:
        """The largest straight distance from the goal to any navigable cell it connects to."""
        rows, cols = np.nonzero(np.isfinite(self.cost))
        if not len(rows):
            return 0.0
        centres = (np.stack([cols, rows], axis=1) + 0.5) * self.navmap.resolution + np.asarray(self.navmap.origin)
        return float(np.linalg.norm(centres - self.goal_xy, axis=1).max())

    def distance(self, xy: np.ndarray) -> np.ndarray:
        """[N] distance on foot (m) from points [N, >=2] to the goal; inf where a point cannot reach it."""
        xy = np.atleast_2d(np.asarray(xy, dtype=np.float64))
        return distances_on_foot([self] * len(xy), xy)


@dataclass(frozen=True)
class ViewpointField:
    """Distances on foot (m) to the nearest of a set of goal cells (ObjectNav's viewpoints: every navigable cell
    within the success radius of any instance of the category). A point's distance is its cell's (after snapping),
    0 on a viewpoint, inf where it cannot reach one: success and the distance to the goal read the same numbers."""

    cells: np.ndarray  # [H, W] bool, the viewpoints
    cost: np.ndarray  # [H, W] m, cell centre -> the nearest viewpoint along the grid; inf where unreachable
    navmap: "NavigableMap"

    @property
    def worst(self) -> float:
        """The largest distance on foot from any connected navigable cell to its nearest viewpoint."""
        finite = self.cost[np.isfinite(self.cost)]
        return float(finite.max()) if finite.size else 0.0

    def distance(self, xy: np.ndarray) -> np.ndarray:
        """[N] distance on foot (m) from points [N, >=2] to the nearest viewpoint; inf where none is reachable."""
        cells = self.navmap.snap(np.atleast_2d(np.asarray(xy, dtype=np.float64))[:, :2])
        out = np.full(len(cells), np.inf)
        ok = cells[:, 0] >= 0
        out[ok] = self.cost[cells[ok, 0], cells[ok, 1]]
        return out


def distances_on_foot(fields: Sequence[GoalField], xy: np.ndarray) -> np.ndarray:
    """[N] distance on foot (m) from each point xy[k] [N, >=2] to the goal of fields[k] (goal fields of one map):
    the env's agents, each walking to its own goal, in one call. Each point's distance is what it alone gives."""
    xy = np.atleast_2d(np.asarray(xy, dtype=np.float64))[:, :2]
    if len(fields) != len(xy):
        raise ValueError(f"expected one goal field per point, got {len(fields)} for {len(xy)} points")
    out = np.full(len(xy), np.inf)
    if not len(xy):
        return out
    navmap = fields[0].navmap
    if any(f.navmap is not navmap for f in fields):
        raise ValueError("the goal fields belong to different maps")
    goals = np.array([f.goal_xy for f in fields], dtype=np.float64).reshape(-1, 2)
    straight = np.linalg.norm(xy - goals, axis=1)
    cells = navmap.snap(xy)
    snapped = cells[:, 0] >= 0
    ok = np.flatnonzero(snapped)
    walk = np.empty(len(ok))
    by_field: dict[int, list[int]] = {}
    for j, k in enumerate(ok.tolist()):
        by_field.setdefault(id(fields[k].cost), []).append(j)
    for js in by_field.values():
        at = cells[ok[js]]
        walk[js] = fields[ok[js[0]]].cost[at[:, 0], at[:, 1]]
    out[ok] = np.maximum(straight[ok], walk)
    check = np.flatnonzero(snapped & (out > straight))  # only where a clear line could shorten it
    clear = check[navmap.clear_to(xy[check], goals[check])]
    out[clear] = straight[clear]
    return out


@dataclass
class NavigableMap:
    """One scene's navigable raster (index [row, col] = [y, x]; origin = world (x, y) of cell (0, 0)'s lower-left
    corner) and its goal fields, each computed once and cached by goal cell."""

    navigable: np.ndarray  # [H, W], nonzero = the agent's centre may stand here
    resolution: float
    origin: tuple[float, float]
    snap_radius: float  # m: a point off the map snaps to navigable floor this near (the agent's radius)
    _fields: dict[tuple[int, int], np.ndarray] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        self.navigable = np.asarray(self.navigable).astype(bool)
        self._graph: csr_matrix | None = None
        self._main: np.ndarray | None = None
        # nearest navigable cell of every cell and its distance (cells, centre to centre)
        self._gap, self._nearest = distance_transform_edt(~self.navigable, return_indices=True)

    def graph(self) -> csr_matrix:
        """The planner's graph of the map (8-connected, no corner cutting; edge weights in cells), built once."""
        if self._graph is None:
            self._graph = grid_graph(self.navigable).tocsr()
        return self._graph

    @property
    def main_region(self) -> np.ndarray:
        """[H, W] bool: the main region (build-scene's largest connected region), computed once."""
        if self._main is None:
            self._main = main_region(self.navigable)
        return self._main

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """x0, y0, x1, y1: the map's extent, m."""
        h, w = self.navigable.shape
        x0, y0 = self.origin
        return x0, y0, x0 + w * self.resolution, y0 + h * self.resolution

    def cell_of(self, xy: np.ndarray) -> np.ndarray:
        """[N, 2] (row, col) of the cells holding points [N, 2] (may lie outside the grid)."""
        xy = np.atleast_2d(np.asarray(xy, dtype=np.float64))[:, :2]
        col_row = np.floor((xy - np.asarray(self.origin)) / self.resolution).astype(np.int64)
        return col_row[:, ::-1]

    def snap(self, xy: np.ndarray) -> np.ndarray:
        """[N, 2] the navigable cell each point stands on or snaps to (within snap_radius); (-1, -1) for none."""
        cells = self.cell_of(xy)
        h, w = self.navigable.shape
        out = np.full_like(cells, -1)
        inside = (cells[:, 0] >= 0) & (cells[:, 0] < h) & (cells[:, 1] >= 0) & (cells[:, 1] < w)
        r, c = cells[inside, 0], cells[inside, 1]
        near = np.stack([self._nearest[0][r, c], self._nearest[1][r, c]], axis=1)
        centre = (near[:, ::-1] + 0.5) * self.resolution + np.asarray(self.origin)
        xy_in = np.atleast_2d(np.asarray(xy, dtype=np.float64))[inside, :2]
        on_nav = self.navigable[r, c]
        close = on_nav | (np.linalg.norm(centre - xy_in, axis=1) <= self.snap_radius)
        out[np.flatnonzero(inside)[close]] = near[close]
        return out

    def place(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points [N, 2] placed on the navigable map: one on a navigable cell as it is, one off it at the centre of
        the cell it snaps to (within snap_radius), NaN where none is that near; and [N] bool, which were moved.
        Points are compared with the map's bounds first, so no coordinate, however large, overflows."""
        xy = np.atleast_2d(np.asarray(xy, dtype=np.float64))[:, :2]
        x0, y0, x1, y1 = self.bounds
        inside = np.flatnonzero((xy[:, 0] >= x0) & (xy[:, 0] < x1) & (xy[:, 1] >= y0) & (xy[:, 1] < y1))
        out, moved = np.full_like(xy, np.nan), np.zeros(len(xy), dtype=bool)
        own, cells = self.cell_of(xy[inside]), self.snap(xy[inside])
        found = cells[:, 0] >= 0
        stays = found & (own == cells).all(axis=1)
        out[inside[stays]] = xy[inside[stays]]
        moves = found & ~stays
        out[inside[moves]] = (cells[moves, ::-1] + 0.5) * self.resolution + np.asarray(self.origin)
        moved[inside[moves]] = True
        return out, moved

    def clear_to(self, xy: np.ndarray, goal_xy: np.ndarray) -> np.ndarray:
        """[N] bool: the straight segment from each point [N, >=2] to the goal ([2], or one per point [N, 2])
        crosses only navigable cells. Each segment is sampled every quarter cell or closer (its own length / its
        own count, ends included), so a point's answer does not depend on the other points asked with it."""
        xy = np.atleast_2d(np.asarray(xy, dtype=np.float64))[:, :2]
        if not len(xy):
            return np.zeros(0, dtype=bool)
        goal = np.broadcast_to(np.asarray(goal_xy, dtype=np.float64).reshape(-1, 2), xy.shape)
        length = np.linalg.norm(xy - goal, axis=1)
        steps = np.ceil(length / (0.25 * self.resolution)).astype(np.int64) + 1
        # sample j of a segment at t = j / steps (np.linspace's values), the far end exactly 1, repeated to the
        # longest segment's count
        j = np.arange(steps.max() + 1)
        t = np.where(j[None, :] < steps[:, None], j[None, :] * (1.0 / steps[:, None]), 1.0)
        samples = xy[:, None, :] + (goal[:, None, :] - xy[:, None, :]) * t[:, :, None]
        cells = self.cell_of(samples.reshape(-1, 2))
        h, w = self.navigable.shape
        inside = (cells[:, 0] >= 0) & (cells[:, 0] < h) & (cells[:, 1] >= 0) & (cells[:, 1] < w)
        free = np.zeros(len(cells), dtype=bool)
        free[inside] = self.navigable[cells[inside, 0], cells[inside, 1]]
        return free.reshape(len(xy), -1).all(axis=1)

    def field(self, goal_xy: np.ndarray) -> GoalField:
        """The distances on foot to `goal_xy` (one Dijkstra per goal cell, cached). A goal off the map (nothing
        navigable within snap_radius) is reachable from nowhere: every distance is inf."""
        goal_xy = np.asarray(goal_xy, dtype=np.float64)[:2]
        r, c = (int(v) for v in self.snap(goal_xy)[0])
        if (r, c) not in self._fields:
            h, w = self.navigable.shape
            if r < 0:
                cost = np.full((h, w), np.inf)
            else:
                cost = dijkstra(self.graph(), directed=True, indices=r * w + c).reshape(h, w) * self.resolution
            self._fields[(r, c)] = cost
        return GoalField(goal_xy, self._fields[(r, c)], self)


    def viewpoint_field(self, cells: np.ndarray) -> ViewpointField:
        """The distances on foot to the nearest of the goal cells ([H, W] bool; only navigable ones count): one
        Dijkstra from all of them at once. No goal cell: reachable from nowhere, every distance inf."""
        goals = np.asarray(cells, dtype=bool) & self.navigable
        sources = np.flatnonzero(goals.ravel())
        if not len(sources):
            return ViewpointField(goals, np.full(goals.shape, np.inf), self)
        cost = dijkstra(self.graph(), directed=True, indices=sources, min_only=True).reshape(goals.shape)
        return ViewpointField(goals, cost * self.resolution, self)


def distance_on_foot(navigable: np.ndarray, resolution: float, origin: tuple[float, float], goal_xy: np.ndarray,
                     *, snap_radius: float) -> GoalField:
    """The distances on foot to one goal over a navigable map; `.distance(points)` gives them at any points."""
    return NavigableMap(navigable, resolution, origin, snap_radius).field(goal_xy)
