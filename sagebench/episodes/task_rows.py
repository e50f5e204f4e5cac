"""Episode rows of the tasks other than vln (docs/tasks.md): nogoal start poses spread over the main region,
objectnav category goals with their viewpoints, pointnav and imagenav point goals; every goal task's reference
path is made as vln's (`astar.sampling.cell_path`).

Distances are shortest paths on the planner's grid graph (8-connected, no corner cutting), from the goal's cells
outwards, so a start is drawn among the main region's cells whose distance lies in [min_geodesic_m,
max_geodesic_m]. Every random choice of a task comes from one generator seeded by (seed, task, scene_id): a scene's
rows depend on nothing else (not on the other tasks asked for, the other scenes, nor the workers).
"""

from __future__ import annotations

import hashlib
import json
import math
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra
from shapely.geometry import MultiPolygon, Polygon

from sagebench.astar.dijkstra_reference import grid_graph
from sagebench.astar.grid_astar import Workspace
from sagebench.astar.sampling import GridMap, cell_path, room_at
from sagebench.astar.shortcut import polyline_length
from sagebench.episodes.ids import episode_id
from sagebench.episodes.splits import assign_splits
from sagebench.episodes.tasks import NOGOAL_INSTRUCTION, VLN, goal_image_recipe, pointgoal_polar
from sagebench.errors import DataError
from sagebench.scene.model import UNLABELLED
from sagebench.settings.gen_trajectories import GenTrajectoriesConfig
from sagebench.topdown.raster import Grid, polygon_mask
from sagebench.topdown.regions import label_regions
from sagebench.topdown.semantic_map import SemanticMap


@dataclass(frozen=True)
class SceneMap:
    """What the tasks sample on: the grid, the main region's standable cells, the grid graph and room floors."""

    grid: GridMap
    nav: np.ndarray  # [H, W] uint8 navigable
    main: np.ndarray  # [H, W] bool: cells the agent's centre may stand on (not passages) in the main region
    graph: csr_matrix
    workspace: Workspace
    rooms: dict[str, MultiPolygon]


def scene_map(grid: GridMap, rooms: dict[str, MultiPolygon]) -> SceneMap:
    nav = np.ascontiguousarray(grid.navigable, dtype=np.uint8)
    labels, count = label_regions(nav)
    biggest = int(np.argmax(np.bincount(labels.ravel())[1:])) + 1 if count else -1  # the lowest id among equals
    return SceneMap(grid, nav, (labels == biggest) & (nav == 1), grid_graph(nav).tocsr(), Workspace(nav.shape), rooms)


def task_rows(scene_id: str, smap: SemanticMap, m: SceneMap, config: GenTrajectoriesConfig,
              where: Path) -> dict[str, list[dict]]:
    """task -> its rows, for every task of `config.tasks` but vln, with their splits. `where` (semantic_map.json)
    is named in the error for a category with no instance."""
    makers = {"nogoal": _nogoal, "objectnav": _objectnav, "pointnav": _point_goal, "imagenav": _point_goal}
    out = {}
    for task in (t for t in config.tasks if t != VLN):
        rng = np.random.default_rng([config.seed, zlib.crc32(f"task {task}|{scene_id}".encode())])
        rows = makers[task](task, scene_id, smap, m, config, rng, where)
        split_of = assign_splits(scene_id, [r["trajectory_id"] for r in rows], config.splits)
        out[task] = [{**r, "split": split_of[r["trajectory_id"]]} for r in rows]
    return out


def _nogoal(task, scene_id, smap, m, config, rng, where) -> list[dict]:
    """Start poses spread over the main region: the first drawn, each next the cell farthest from those taken."""
    cells = np.argwhere(m.main)
    if len(cells) == 0:
        return []
    taken = [int(rng.integers(len(cells)))]
    gap = np.full(len(cells), np.inf)
    for _ in range(min(config.task.episodes, len(cells)) - 1):
        gap = np.minimum(gap, np.hypot(*(cells - cells[taken[-1]]).T))
        taken.append(int(np.argmax(gap)))
    rows = []
    for i in taken:
        rows.append(_row(task, scene_id, m, config, _world(m, cells[i][None]), 0.0, rng, budget_s=config.task.nogoal_budget_s,
                         budget_steps=config.task.nogoal_budget_steps, instruction_text=NOGOAL_INSTRUCTION,
                         instruction_source="template"))
    return rows


def _objectnav(task, scene_id, smap, m, config, rng, where) -> list[dict]:
    """Each episode a category (in turn, in a shuffled order); its goal, the nearest viewpoint of any instance."""
    goals = _category_goals(smap, m, config, where)
    names = sorted(goals)
    names = [names[i] for i in rng.permutation(len(names))]
    radius = config.task.objectnav_success_m
    fields = {c: _distances(m, goals[c][1], config.max_geodesic_m) for c in names}
    rows = []
    for k in range(config.task.episodes if names else 0):
        category = names[k % len(names)]
        ids, viewpoints = goals[category]
        dist, nearest = fields[category]
        start = _draw_start(m, dist, config, rng)
        if start is None:
            continue
        wps = cell_path(m.nav, m.grid, start, viewpoints[nearest[tuple(start)]], m.workspace)[1]
        rows.append(_row(task, scene_id, m, config, wps, radius, rng, goal_category=category, goal_instance_ids=ids,
                         goal_viewpoints=cell_points(m, viewpoints),
                         instruction_text=f"Find the {category.replace('_', ' ')}", instruction_source="template"))
    return rows


def _category_goals(smap: SemanticMap, m: SceneMap, config: GenTrajectoriesConfig,
                    where: Path) -> dict[str, tuple[list[int], np.ndarray]]:
    """category -> (its instance ids, its viewpoint cells [K, 2]): the asked categories (each must have an instance
    with a viewpoint), else every object category that has one; never the unlabelled obstacles (nothing to look for)."""
    asked = config.task.objectnav_categories
    if UNLABELLED in (asked or ()):
        raise DataError(f"objectnav category {UNLABELLED!r}: geometry no label explains has no name to look for; "
                        f"nothing written", path=where, field="--objectnav-categories")
    out = {}
    for category in asked or sorted({i.category for i in smap.instances if i.kind == "object"} - {UNLABELLED}):
        ids, viewpoints = category_viewpoints(smap, m, category, config.task.objectnav_success_m)
        if len(viewpoints):
            out[category] = (ids, viewpoints)
        elif asked:
            why = "no instance" if not ids else \
                f"no navigable cell of the main region within {config.task.objectnav_success_m:g} m of an instance"
            raise DataError(f"objectnav category {category!r}: {why}; nothing written", path=where,
                            field="--objectnav-categories")
    return out


def category_viewpoints(smap: SemanticMap, m: SceneMap, category: str, radius: float) -> tuple[list[int], np.ndarray]:
    """The ids of `category`'s instances (those with a footprint) and its goal viewpoints, cells [K, 2]: the main
    region's standable cells whose centre lies within `radius` of any instance's footprint cell."""
    instances = [i for i in smap.instances if i.category == category and i.polygon.coordinates]
    grid = Grid(m.grid.origin, m.grid.resolution, m.nav.shape)
    footprint = np.zeros(m.nav.shape, dtype=bool)
    for inst in instances:
        footprint |= polygon_mask(MultiPolygon([Polygon(p[0], p[1:]) for p in inst.polygon.coordinates]), grid)
    if not footprint.any():
        return [i.instance_id for i in instances], np.zeros((0, 2), dtype=np.int64)
    near = ndimage.distance_transform_edt(~footprint) * grid.resolution <= radius
    return [i.instance_id for i in instances], np.argwhere(m.main & near)


def cell_points(m: SceneMap, cells: np.ndarray) -> list[list[float]]:
    """[K, 3] x, y, floor z of cell centres: goal viewpoints as an episode row holds them."""
    return _world(m, cells)[:, :3].tolist()


def _point_goal(task, scene_id, smap, m, config, rng, where) -> list[dict]:
    """A goal cell drawn from the main region, then a start at a distance in range from it (another goal when
    none is); pointnav's goal in the start frame, imagenav's goal camera looking along the path's last heading."""
    cells = np.argwhere(m.main)
    rows: list[dict] = []
    for _ in range(10 * config.task.episodes if len(cells) else 0):
        if len(rows) == config.task.episodes:
            break
        goal = cells[int(rng.integers(len(cells)))]
        start = _draw_start(m, _distances(m, goal[None], config.max_geodesic_m)[0], config, rng)
        if start is None:
            continue
        wps = cell_path(m.nav, m.grid, start, goal, m.workspace)[1]
        if task == "pointnav":
            row = _row(task, scene_id, m, config, wps, config.task.pointnav_success_m, rng)
            row["goal_polar"] = list(pointgoal_polar(*wps[0, :2], row["start_yaw"], *wps[-1, :2]))
        else:
            row = _row(task, scene_id, m, config, wps, config.task.imagenav_success_m, rng, goal_yaw=float(wps[-1, 3]),
                       goal_image=goal_image_recipe(*wps[-1, [0, 1, 3]].tolist()))
        rows.append(row)
    return rows


def _distances(m: SceneMap, sources: np.ndarray, limit_m: float) -> tuple[np.ndarray, np.ndarray]:
    """[H, W] shortest-path distance (m) from the nearest of `sources` ([K, 2] cells; inf beyond `limit_m` and where
    unreachable), and [H, W] the index into `sources` of that nearest one (-1 where inf)."""
    h, w = m.nav.shape
    nodes = sources[:, 0] * w + sources[:, 1]
    dist, _, src = dijkstra(m.graph, directed=False, indices=nodes, min_only=True, return_predecessors=True,
                            limit=limit_m / m.grid.resolution)
    lookup = np.full(h * w, -1, dtype=np.int64)
    lookup[nodes] = np.arange(len(nodes))
    return dist.reshape(h, w) * m.grid.resolution, np.where(src >= 0, lookup[src], -1).reshape(h, w)


def _draw_start(m: SceneMap, dist: np.ndarray, config: GenTrajectoriesConfig,
                rng: np.random.Generator) -> np.ndarray | None:
    """A main-region cell whose distance lies in [min_geodesic_m, max_geodesic_m], or None when there is none."""
    ok = np.argwhere(m.main & (dist >= config.min_geodesic_m) & (dist <= config.max_geodesic_m))
    return ok[int(rng.integers(len(ok)))] if len(ok) else None


def _world(m: SceneMap, cells: np.ndarray) -> np.ndarray:
    """[K, 4] x, y, floor z, 0 of cell centres."""
    g = m.grid
    out = np.zeros((len(cells), 4), dtype=np.float64)
    out[:, 0] = g.origin[0] + (cells[:, 1] + 0.5) * g.resolution
    out[:, 1] = g.origin[1] + (cells[:, 0] + 0.5) * g.resolution
    out[:, 2] = g.floor_z
    return out


def _row(task: str, scene_id: str, m: SceneMap, config: GenTrajectoriesConfig, wps: np.ndarray, radius: float,
         rng: np.random.Generator, **fields) -> dict:
    """The shared columns of a task row from its reference path (the start alone for nogoal). The start heading is
    drawn uniformly, as habitat's episodes start, so that a goal is not straight ahead."""
    trajectory_id = hashlib.sha256(json.dumps([scene_id, task, np.round(wps, 4).tolist()]).encode()).hexdigest()[:16]
    return {"episode_id": episode_id(trajectory_id, task, "", 0), "trajectory_id": trajectory_id,
            "scene_id": scene_id, "instruction_level": None, "instruction_type": None, "instruction_text": None,
            "instruction_source": None, "start_instance_id": None, "goal_instance_id": None,
            "start_room": room_at(wps[0, :2], m.rooms), "goal_room": room_at(wps[-1, :2], m.rooms),
            "start_position": wps[0, :3].tolist(), "start_yaw": float(rng.uniform(-math.pi, math.pi)),
            "goal_position": wps[-1, :3].tolist(), "goal_radius": radius, "reference_path": wps.tolist(),
            "geodesic_distance": polyline_length(wps), "seed": config.seed, "task": task, **fields}
