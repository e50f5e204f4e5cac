"""Episode sampling: reachable start/goal pairs of objects and rooms, their A* paths and waypoints.

How a pair becomes a trajectory (SAGE-Bench's recipe, made concrete):
- an object is approached at the navigable cells nearest its footprint (within `approach_tolerance_m`
  of the nearest, and no farther than `approach_max_m`); among those, the start uses the cell facing
  the goal and the goal the cell facing the start (smallest straight-line distance);
- a room is stood in at its navigable cell nearest the room polygon's centroid;
- the pair is kept when A* finds a path whose waypoint length lies in [min_geodesic_m, max_geodesic_m];
- ordered pairs are drawn without replacement, interleaving the pair kinds by `pair_mix`, until
  `per_scene` distinct trajectories are found or the candidates run out.
Everything random comes from one generator seeded by (seed, scene_id).
"""

from __future__ import annotations

import hashlib
import json
import zlib
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Literal

import cv2
import numpy as np
from scipy import ndimage
from shapely.geometry import MultiPolygon, Point, Polygon

from sagebench.astar.grid_astar import GridPath, Workspace, astar
from sagebench.astar.shortcut import polyline_length, shortcut_indices, waypoints
from sagebench.settings.gen_trajectories import SamplingConfig


@dataclass(frozen=True)
class GridMap:
    """The navigable raster of one scene. Index [row, col] = [y, x]; origin = world (x, y) of cell (0, 0)'s lower-left corner."""

    navigable: np.ndarray  # [H, W] uint8, 1 = the agent's centre may stand here, 2 = a passage cell, at its anchor
    resolution: float  # metres per cell
    origin: tuple[float, float]  # world metres
    floor_z: float  # metres
    anchors: dict[tuple[int, int], tuple[float, float]] = field(default_factory=dict)  # passage cell -> world xy


@dataclass(frozen=True)
class TargetSpec:
    """Something a trajectory starts or ends at: an object (by instance id) or a room."""

    key: str  # unique within the scene, e.g. "object:41" or "room:room_2"; never shown to people
    kind: Literal["object", "room"]
    instance_id: int | None  # None for a room
    room_id: str | None  # the room it is in (its own id for a room)
    outlines: tuple[np.ndarray, ...]  # each [N, 2] float64: exterior rings of the footprint or floor, world metres


@dataclass(frozen=True)
class Trajectory:
    trajectory_id: str  # hash of scene id, endpoints and waypoints
    start: TargetSpec
    goal: TargetSpec
    cells: np.ndarray  # [K, 2] int32 A* grid path (row, col)
    waypoints: np.ndarray  # [M, 4] float64 (x, y, z, yaw) after shortcutting
    grid_length_m: float  # A* cost along the grid path
    path_length_m: float  # length of the waypoint polyline (<= grid_length_m)
    start_room: str | None = None  # the room the start position lies in (not the start target's annotation)
    goal_room: str | None = None  # the room the goal position lies in


@dataclass(frozen=True)
class SamplingResult:
    trajectories: list[Trajectory]
    pairs_tried: int
    rejected: dict[str, int]  # reason -> number of pairs
    unreachable_targets: list[str]  # keys of targets with no stand point


@dataclass(frozen=True)
class _Stand:
    """Where a target can be stood at: candidate cells and the component each lies in."""

    cells: np.ndarray  # [M, 2] int64
    components: np.ndarray  # [M] int, label of the navigable component
    anchor: np.ndarray  # [2] float64 (row, col) of the footprint centroid


def sample_trajectories(grid: GridMap, targets: Sequence[TargetSpec], scene_id: str,
                        config: SamplingConfig) -> SamplingResult:
    """Up to `config.per_scene` distinct trajectories between `targets`, deterministic for (seed, scene_id)."""
    nav = np.ascontiguousarray(grid.navigable, dtype=np.uint8)
    labels, _ = ndimage.label(nav)  # 4-connectivity = 8-connectivity without corner cutting
    stands: dict[str, _Stand] = {}
    unreachable = []
    for t in targets:
        stand = _stand_cells(nav, labels, grid, t, config)
        if stand is None:
            unreachable.append(t.key)
        else:
            stands[t.key] = stand
    usable = [t for t in targets if t.key in stands]
    rooms = {t.room_id: MultiPolygon([Polygon(r) for r in t.outlines]) for t in targets
             if t.kind == "room" and t.room_id is not None}
    rng = np.random.default_rng([config.seed, zlib.crc32(scene_id.encode())])
    queues = _pair_queues(usable, rng)
    workspace = Workspace(nav.shape)
    rejected: Counter[str] = Counter()
    seen: set[tuple[int, int, int, int]] = set()
    out: list[Trajectory] = []
    tried = 0
    taken = {kind: 0 for kind in queues}
    while len(out) < config.per_scene:
        kind = _next_kind(queues, taken, config.pair_mix)
        if kind is None:
            break
        start, goal = queues[kind].pop()
        taken[kind] += 1
        tried += 1
        traj, reason = _try_pair(nav, grid, stands[start.key], stands[goal.key], start, goal, scene_id, config,
                                 workspace, rooms)
        if traj is None:
            rejected[reason] += 1
            continue
        key = (*traj.cells[0].tolist(), *traj.cells[-1].tolist())
        if key in seen:
            rejected["same endpoints as another trajectory"] += 1
            continue
        seen.add(key)
        out.append(traj)
    return SamplingResult(out, tried, dict(sorted(rejected.items())), unreachable)


def _pair_queues(targets: Sequence[TargetSpec], rng: np.random.Generator) -> dict[str, list[tuple[TargetSpec, TargetSpec]]]:
    """Shuffled ordered pairs of distinct targets per pair kind (popped from the end)."""
    queues: dict[str, list[tuple[TargetSpec, TargetSpec]]] = {}
    for a in targets:
        for b in targets:
            if a.key != b.key:
                queues.setdefault(f"{a.kind}-{b.kind}", []).append((a, b))
    for pairs in queues.values():
        order = rng.permutation(len(pairs))
        pairs[:] = [pairs[i] for i in order]
    return queues


def _next_kind(queues: dict[str, list], taken: dict[str, int], mix: dict[str, float]) -> str | None:
    """The pair kind furthest behind its share of `mix` that still has candidates."""
    live = [k for k in sorted(queues) if queues[k] and mix.get(k, 0) > 0]
    if not live:
        return None
    return min(live, key=lambda k: taken[k] / mix[k])


def _try_pair(nav, grid: GridMap, s: _Stand, g: _Stand, start: TargetSpec, goal: TargetSpec, scene_id: str,
              config: SamplingConfig, workspace: Workspace,
              rooms: dict[str, MultiPolygon]) -> tuple[Trajectory | None, str]:
    ok = np.isin(s.components, g.components)
    if not ok.any():
        return None, "goal not reachable from start"
    s_cells, s_comps = s.cells[ok], s.components[ok]
    i = int(np.argmin(_sq_dist(s_cells, g.anchor)))  # the start faces the goal ...
    s_cell = s_cells[i]
    g_cells = g.cells[g.components == s_comps[i]]
    g_cell = g_cells[np.argmin(_sq_dist(g_cells, s_cell))]  # ... and the goal faces the start
    if np.sqrt(_sq_dist(g_cell[None], s_cell)[0]) * grid.resolution > config.max_geodesic_m:
        return None, "longer than max_geodesic_m"
    found = cell_path(nav, grid, s_cell, g_cell, workspace)
    if found is None:
        return None, "goal not reachable from start"
    path, wps = found
    length = polyline_length(wps)
    if length < config.min_geodesic_m:
        return None, "shorter than min_geodesic_m"
    if length > config.max_geodesic_m:
        return None, "longer than max_geodesic_m"
    start_room, goal_room = room_at(wps[0, :2], rooms), room_at(wps[-1, :2], rooms)
    if goal.kind == "room" and start_room == goal.room_id:
        return None, "starts inside the goal room"
    return Trajectory(_trajectory_id(scene_id, start, goal, wps), start, goal, path.cells, wps, path.cost, length,
                      start_room, goal_room), ""


def cell_path(nav: np.ndarray, grid: GridMap, a: np.ndarray, b: np.ndarray,
              workspace: Workspace) -> tuple[GridPath, np.ndarray] | None:
    """The A* grid path from cell `a` to cell `b` ((row, col)) and its shortcut waypoints [M, 4], or None when `b`
    is unreachable: every episode's reference path, whatever its task, is made this way."""
    path = astar(nav, (int(a[0]), int(a[1])), (int(b[0]), int(b[1])), grid.resolution, workspace)
    if path is None:
        return None
    keep = shortcut_indices(nav, path.cells)
    return path, waypoints(path.cells[keep], grid.resolution, grid.origin, grid.floor_z, grid.anchors)


def room_at(xy: np.ndarray, rooms: dict[str, MultiPolygon]) -> str | None:
    """The first room (by id) whose floor covers world point `xy` [2] (its boundary included), else None."""
    p = Point(float(xy[0]), float(xy[1]))
    return next((rid for rid in sorted(rooms) if rooms[rid].covers(p)), None)


def _sq_dist(cells: np.ndarray, point: np.ndarray) -> np.ndarray:
    d = cells.astype(np.float64) - point
    return d[:, 0] ** 2 + d[:, 1] ** 2


def _trajectory_id(scene_id: str, start: TargetSpec, goal: TargetSpec, wps: np.ndarray) -> str:
    """Stable id: the same scene, endpoints and waypoints (to 0.1 mm) give the same id on any machine."""
    content = json.dumps([scene_id, start.key, goal.key, np.round(wps, 4).tolist()])
    return hashlib.sha256(content.encode()).hexdigest()[:16]


def _stand_cells(nav: np.ndarray, labels: np.ndarray, grid: GridMap, target: TargetSpec,
                 config: SamplingConfig) -> _Stand | None:
    """The cells to stand at for `target`, or None when no navigable cell is close enough."""
    res = grid.resolution
    h, w = nav.shape
    rings = [(np.asarray(r, dtype=np.float64) - np.asarray(grid.origin)) / res for r in target.outlines]  # (col, row)
    poly = np.concatenate(rings)
    centroid = MultiPolygon([Polygon(r) for r in rings]).centroid
    anchor = np.array([centroid.y, centroid.x]) if not centroid.is_empty else poly.mean(axis=0)[::-1]
    margin = 0 if target.kind == "room" else int(np.ceil(config.approach_max_m / res)) + 1
    r0 = max(int(np.floor(poly[:, 1].min())) - margin, 0)
    r1 = min(int(np.ceil(poly[:, 1].max())) + margin + 1, h)
    c0 = max(int(np.floor(poly[:, 0].min())) - margin, 0)
    c1 = min(int(np.ceil(poly[:, 0].max())) + margin + 1, w)
    if r0 >= r1 or c0 >= c1:
        return None
    inside = _rasterise([r - [c0, r0] for r in rings], (r1 - r0, c1 - c0))
    window = nav[r0:r1, c0:c1] == 1  # never in a passage (its anchor is no place to start or stop)
    if target.kind == "room":
        free = window & inside
        d = np.hypot(*(np.indices(free.shape) - (anchor - [r0, c0])[:, None, None])) * res
    else:
        free = window
        d = ndimage.distance_transform_edt(~inside) * res if inside.any() else np.full(free.shape, np.inf)
        free = free & (d <= config.approach_max_m)
    if not free.any():
        return None
    rows, cols = np.nonzero(free & (d <= d[free].min() + config.approach_tolerance_m))
    cells = np.column_stack([rows + r0, cols + c0]).astype(np.int64)
    return _Stand(cells, labels[cells[:, 0], cells[:, 1]], anchor)


def _rasterise(rings: list[np.ndarray], shape: tuple[int, int]) -> np.ndarray:
    """[h, w] bool: cells whose centre lies inside any ring ((col, row) cell units), plus their outline cells."""
    mask = np.zeros(shape, dtype=np.uint8)
    for ring in rings:  # one at a time: cv2 fills several rings even-odd, and footprints may overlap
        pts = np.round((ring - 0.5) * 16).astype(np.int32)  # cv2: pixel centres at integers; 4-bit subpixel
        cv2.fillPoly(mask, [pts], 1, lineType=cv2.LINE_8, shift=4)
    return mask.astype(bool)
