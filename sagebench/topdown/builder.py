"""The map builder: a loaded scene -> its top-down maps (instance, category, occupancy, navigable, regions)
and the semantic report, computed without I/O (build-scene writes them), in named steps, each a function of
the results before it, testable alone:

1. footprints: `footprints.object_footprints`, each object's outline seen from above;
2. the floor plan and the map's grid: `floor_plan`, `map_grid` (below);
3. occupancy: `occupancy.scene_occupancy`, what blocks in the height band and where the agent fits;
4. passages: `passages.open_passages`, narrow gaps between regions re-judged on the exact geometry;
5. the instance and category rasters: `paint_instances`, `paint_categories` (below);
6. regions: `regions.room_reachability`, the navigable map's connected regions and the rooms they hold;
7. the semantic map: `semantic_report` (below), semantic_map.json from the results of all the others.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from sagebench.errors import ConfigError, SceneError
from sagebench.scene.checks import NO_FLOOR
from sagebench.scene.loader import SCENE_FILE, LoadedScene
from sagebench.scene.model import Room, SceneObject, SceneSpec
from sagebench.settings.build_scene import BuildSceneConfig
from sagebench.settings.shared import AgentConfig
from sagebench.topdown.footprints import mesh_parts, object_footprints
from sagebench.topdown.occupancy import blockers, scene_occupancy
from sagebench.topdown.passages import Passages, open_passages
from sagebench.topdown.raster import Grid, polygon_mask
from sagebench.topdown.regions import Reachability, room_reachability
from sagebench.topdown.semantic_map import DECIMALS, MapInstance, MultiPolygon, Region, RoomReach, SemanticMap

THIN_KINDS = frozenset({"door", "window"})  # painted where they touch a cell, so a 4 cm leaf shows


@dataclass(frozen=True)
class Topdown:
    """Everything build-scene computes, before it is written."""

    grid: Grid
    instance: np.ndarray  # [H, W] int32, instance id per cell, 0 background
    category: np.ndarray  # [H, W] int16, category id per cell (index into categories), 0 background
    occupancy: np.ndarray  # [H, W] uint8, 1 blocked, 0 free
    navigable: np.ndarray  # [H, W] uint8, 1 where the agent's centre may stand, PASSAGE: at the cell's anchor
    region: np.ndarray  # [H, W] int32, connected navigable region id, 0 elsewhere
    categories: list[str]
    semantic: SemanticMap
    footprints: dict[int, BaseGeometry]  # instance id -> footprint, world m
    passages: Passages  # the cells of narrow passages opened on the exact geometry, and their anchors


def compute_topdown(scene: LoadedScene, config: BuildSceneConfig) -> Topdown:
    """The maps and the semantic report of a loaded scene (no I/O), step by step (the module docstring)."""
    scene_grid(scene, config.resolution)  # refuses a map over the cell budget before any work
    objects, radius = scene.spec.objects, config.agent.radius
    band = height_band(scene.spec, config.agent)
    parts = {o.instance_id: mesh_parts(scene.meshes[o.instance_id]) for o in objects}
    footprints = object_footprints(scene, parts, band, config)
    plan = floor_plan(scene, footprints, config.wall_gap)
    grid = map_grid(scene, plan, config.resolution)
    occ = scene_occupancy(objects, parts, plan, grid, band, radius)
    navigable, passages = open_passages(occ.navigable, occ.occupied, occ.band_polys, plan, grid, radius)
    categories = category_names(objects)
    instance = paint_instances(scene, footprints, grid, band)
    reach = room_reachability(navigable, scene.spec.rooms, grid)
    semantic = semantic_report(scene, config, grid=grid, footprints=footprints, categories=categories,
                               blocking=occ.blocking, navigable=navigable, reach=reach)
    return Topdown(grid=grid, instance=instance, category=paint_categories(instance, objects, categories),
                   occupancy=occ.occupied.astype(np.uint8), navigable=navigable.astype(np.uint8),
                   region=reach.labels, categories=categories, semantic=semantic, footprints=footprints,
                   passages=passages)


def scene_grid(scene: LoadedScene, resolution: float) -> Grid:
    """A grid covering every mesh and room of the scene: at least the map's (ConfigError over the cell budget)."""
    boxes = [m.bounds[:, :2] for m in scene.meshes.values()]
    boxes += [np.array([np.min(r.polygon, axis=0), np.max(r.polygon, axis=0)]) for r in scene.spec.rooms]
    lo, hi = np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)
    try:
        return Grid.covering(lo, hi, resolution, margin=2 * resolution)
    except ConfigError as err:
        raise ConfigError(err.detail, path=scene.source_dir, field=err.field) from None


def height_band(spec: SceneSpec, agent: AgentConfig) -> tuple[float, float]:
    """World z (lo, hi) of the band whose geometry blocks, m: the agent's body, measured from the floor."""
    z_lo, z_hi = (spec.floor_height + z for z in agent.band)
    return z_lo, z_hi


def floor_plan(scene: LoadedScene, footprints: Mapping[int, BaseGeometry], wall_gap: float) -> BaseGeometry:
    """Where the floor is: the room polygons (else the floor meshes' footprints), joined across walls.

    Room polygons stop at the wall faces, so a doorway lies outside all of them; closing the union by
    `wall_gap` (grow, then shrink, square corners kept) makes walls up to that thick part of the plan,
    where their own geometry blocks and their openings let the agent through.
    """
    spec = scene.spec
    if spec.rooms:
        shapes = [shapely.Polygon(r.polygon).buffer(0) for r in spec.rooms]
    else:
        shapes = [footprints[o.instance_id] for o in spec.objects if o.kind == "floor"]
    plan = shapely.union_all(shapes)
    if plan.is_empty or plan.area <= 0:
        raise SceneError(NO_FLOOR, path=scene.source_dir / SCENE_FILE, field="rooms")
    if wall_gap > 0:
        plan = plan.buffer(wall_gap / 2, join_style="mitre").buffer(-wall_gap / 2, join_style="mitre")
    return plan


def map_grid(scene: LoadedScene, plan: BaseGeometry, resolution: float) -> Grid:
    """The map's grid: cells `resolution` m square covering the floor plan and every object that may block
    (`occupancy.blockers`), with two cells of margin."""
    boxes = [scene.meshes[o.instance_id].bounds for o in blockers(scene.spec.objects)]
    los = [plan.bounds[:2]] + [b[0][:2] for b in boxes]
    his = [plan.bounds[2:]] + [b[1][:2] for b in boxes]
    return Grid.covering(np.min(los, axis=0), np.max(his, axis=0), resolution, margin=2 * resolution)


def category_names(objects: Sequence[SceneObject]) -> list[str]:
    """Category id -> name: 'background' (id 0), then the scene's categories sorted, so equal scenes number alike."""
    return ["background", *sorted({o.category for o in objects})]


def paint_instances(scene: LoadedScene, footprints: Mapping[int, BaseGeometry], grid: Grid,
                    band: tuple[float, float]) -> np.ndarray:
    """[H, W] int32 instance id per cell of `grid`: footprints painted floor first, things outside the `band`
    (world z lo, hi, m) next, then the rest from low to high (a TV over its stand), then walls, then the doors
    and windows set in them. Ceilings are left out: they would cover everything.
    """
    z_lo, z_hi = band

    def order(o: SceneObject) -> tuple:
        lo, hi = scene.meshes[o.instance_id].bounds[:, 2]
        if o.kind == "floor":
            rank = 0
        elif o.kind == "wall":
            rank = 3
        elif o.kind in THIN_KINDS:
            rank = 4
        else:
            rank = 1 if (hi < z_lo or lo > z_hi) else 2
        return (rank, round(float(hi), 6), o.instance_id)

    out = np.zeros(grid.shape, dtype=np.int32)
    for o in sorted((o for o in scene.spec.objects if o.kind != "ceiling"), key=order):
        out[polygon_mask(footprints[o.instance_id], grid, touch=o.kind in THIN_KINDS)] = o.instance_id
    return out


def paint_categories(instance: np.ndarray, objects: Sequence[SceneObject], categories: list[str]) -> np.ndarray:
    """[H, W] int16 category id per cell (index into `categories`, 0 background) of the [H, W] instance raster."""
    cat_id = {c: i for i, c in enumerate(categories)}
    lut = np.zeros(max(o.instance_id for o in objects) + 1, dtype=np.int16)
    for o in objects:
        lut[o.instance_id] = cat_id[o.category]
    return lut[instance]


def semantic_report(scene: LoadedScene, config: BuildSceneConfig, *, grid: Grid,
                    footprints: Mapping[int, BaseGeometry], categories: list[str], blocking: frozenset[int],
                    navigable: np.ndarray, reach: Reachability) -> SemanticMap:
    """semantic_map.json from the steps' results: the map's frame and band, every object (`map_instances`), the
    navigable area (`navigable`: [H, W] on `grid`, nonzero = navigable), its regions and each room's reach."""
    spec, cell = scene.spec, grid.cell_area()
    z_lo, z_hi = height_band(spec, config.agent)
    return SemanticMap(
        scene_id=spec.scene_id, resolution=grid.resolution, origin=grid.origin, shape=grid.shape,
        floor_height=spec.floor_height, band_m=(_r(z_lo), _r(z_hi)), agent_radius=config.agent.radius,
        categories=categories,
        instances=map_instances(scene, footprints, categories, blocking),
        navigable_area_m2=_r(float(np.count_nonzero(navigable)) * cell),
        regions=[Region(region_id=k, area_m2=_r(n * cell),
                        rooms=sorted(r for r, regs in reach.room_regions.items() if k in regs))
                 for k, n in enumerate(reach.region_cells, start=1)],
        main_region=reach.main_region,
        rooms=[room_reach(r, reach, cell) for r in spec.rooms],
        all_rooms_connected=reach.all_rooms_connected(),
    )


def map_instances(scene: LoadedScene, footprints: Mapping[int, BaseGeometry], categories: list[str],
                  blocking: frozenset[int]) -> list[MapInstance]:
    """One record per object, in scene order: category id (index into `categories`), room, footprint, box and
    heights (m), and whether it blocks (its instance id in `blocking`)."""
    cat_id = {c: i for i, c in enumerate(categories)}
    out = []
    for o in scene.spec.objects:
        fp, (lo, hi) = footprints[o.instance_id], scene.meshes[o.instance_id].bounds
        out.append(MapInstance(
            instance_id=o.instance_id, category=o.category, category_id=cat_id[o.category], kind=o.kind,
            room=o.room_id or _room_of(fp, scene.spec.rooms), polygon=_geojson(fp),
            bbox_m=(tuple(_r(v) for v in lo), tuple(_r(v) for v in hi)), area_m2=_r(fp.area),
            min_z=_r(lo[2]), max_z=_r(hi[2]), door_state=o.door.state if o.door else None,
            blocks=o.instance_id in blocking,
        ))
    return out


def room_reach(room: Room, reach: Reachability, cell: float) -> RoomReach:
    """A room's line of the reachability report; `cell`: the area of one cell, m^2."""
    return RoomReach(
        room_id=room.id, type=room.type, navigable_area_m2=_r(reach.room_cells[room.id] * cell),
        regions=list(reach.room_regions[room.id]), reachable=reach.room_reachable(room.id),
        unreachable_area_m2=_r(reach.unreachable_cells(room.id) * cell),
        reachable_rooms=list(reach.reachable_from(room.id)),
    )


def _room_of(fp: BaseGeometry, rooms: Sequence[Room]) -> str | None:
    c = fp.centroid
    return next((r.id for r in rooms if shapely.Polygon(r.polygon).covers(c)), None) if not c.is_empty else None


def _geojson(geom: BaseGeometry) -> MultiPolygon:
    polys = [p for p in getattr(geom, "geoms", [geom]) if isinstance(p, shapely.Polygon) and not p.is_empty]
    polys = [shapely.geometry.polygon.orient(p) for p in polys]  # exterior counter-clockwise, holes clockwise
    return MultiPolygon(coordinates=[
        [[(_r(x), _r(y)) for x, y in ring.coords] for ring in (p.exterior, *p.interiors)] for p in polys
    ])


def _r(v: float) -> float:
    return round(float(v), DECIMALS)
