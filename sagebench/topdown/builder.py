"""The map builder: a loaded scene -> its top-down maps (instance, category, occupancy, navigable, regions)
and the semantic report, computed without I/O (build-scene writes them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from sagebench.errors import ConfigError, SceneError
from sagebench.scene.checks import NO_FLOOR
from sagebench.scene.loader import SCENE_FILE, LoadedScene
from sagebench.settings.build_scene import BuildSceneConfig
from sagebench.topdown.footprints import band_section, footprint, mesh_parts
from sagebench.topdown.occupancy import band_occupancy, clip_to_band, inflate
from sagebench.topdown.passages import Passages, open_passages
from sagebench.topdown.raster import Grid, polygon_mask
from sagebench.topdown.regions import reachability
from sagebench.topdown.semantic_map import DECIMALS, MapInstance, MultiPolygon, Region, RoomReach, SemanticMap
from sagebench.ui import track

NOT_BLOCKING_KINDS = frozenset({"floor", "ceiling"})  # walkable surfaces and what is above every head
THIN_KINDS = frozenset({"door", "window"})  # painted where they touch a cell, so a 4 cm leaf shows
BAND_SECTION_KINDS = frozenset({"wall"})  # footprint: where they stand in the band (doorways stay open), not hulls


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
    """The maps and the semantic report of a loaded scene (no I/O)."""
    scene_grid(scene, config.resolution)  # refuses a map over the cell budget before any work
    spec = scene.spec
    res = config.resolution
    z_lo, z_hi = (spec.floor_height + z for z in config.agent.band)  # the band is measured from the floor
    objects = spec.objects
    parts = {o.instance_id: mesh_parts(scene.meshes[o.instance_id]) for o in objects}
    footprints: dict[int, BaseGeometry] = {}
    for o in track(objects, "footprints"):
        if o.kind in BAND_SECTION_KINDS:
            fp = band_section(scene.meshes[o.instance_id], z_lo, z_hi, min_width=res)
        else:
            tris, part = parts[o.instance_id]
            rng = np.random.default_rng([config.seed, o.instance_id])
            fp = footprint(tris, part, config.sample_density, rng, min_width=res)
        footprints[o.instance_id] = fp.simplify(res / 10)  # drops the near-collinear sample and section corners

    plan = floor_plan(scene, footprints, config.wall_gap)
    blockers = [o for o in objects if o.kind not in NOT_BLOCKING_KINDS]
    los = [plan.bounds[:2]] + [scene.meshes[o.instance_id].bounds[0][:2] for o in blockers]
    his = [plan.bounds[2:]] + [scene.meshes[o.instance_id].bounds[1][:2] for o in blockers]
    grid = Grid.covering(np.min(los, axis=0), np.max(his, axis=0), res, margin=2 * res)

    tris, part, owner = _stack([parts[o.instance_id] for o in blockers])
    occupied = band_occupancy(tris, part, grid, z_lo, z_hi) | ~polygon_mask(plan, grid)
    navigable = inflate(occupied, config.agent.radius, res)
    if not navigable.any():
        raise ConfigError(f"an agent of radius {config.agent.radius:g} m fits nowhere on the floor: no navigable cell "
                          "(a smaller agent radius, or a scene with free floor)", field="agent.radius")
    polys, src = clip_to_band(tris, z_lo, z_hi)
    navigable, passages = open_passages(navigable, occupied, polys, plan, grid, config.agent.radius)
    blocking_ids = {blockers[i].instance_id for i in np.unique(owner[src])}

    categories = ["background", *sorted({o.category for o in objects})]
    cat_id = {c: i for i, c in enumerate(categories)}
    bounds = {o.instance_id: scene.meshes[o.instance_id].bounds for o in objects}
    instance = paint_instances(objects, footprints, bounds, grid, z_lo, z_hi)
    lut = np.zeros(max(o.instance_id for o in objects) + 1, dtype=np.int16)
    for o in objects:
        lut[o.instance_id] = cat_id[o.category]
    category = lut[instance]

    room_masks = {r.id: polygon_mask(shapely.Polygon(r.polygon), grid) for r in spec.rooms}
    reach = reachability(navigable, room_masks)
    cell = grid.cell_area()
    region_rooms = {k: sorted(r for r, regs in reach.room_regions.items() if k in regs)
                    for k in range(1, len(reach.region_cells) + 1)}
    semantic = SemanticMap(
        scene_id=spec.scene_id,
        resolution=res,
        origin=grid.origin,
        shape=grid.shape,
        floor_height=spec.floor_height,
        band_m=(_r(z_lo), _r(z_hi)),
        agent_radius=config.agent.radius,
        categories=categories,
        instances=[
            MapInstance(
                instance_id=o.instance_id,
                category=o.category,
                category_id=cat_id[o.category],
                kind=o.kind,
                room=o.room_id or _room_of(footprints[o.instance_id], spec.rooms),
                polygon=_geojson(footprints[o.instance_id]),
                bbox_m=(tuple(_r(v) for v in bounds[o.instance_id][0]), tuple(_r(v) for v in bounds[o.instance_id][1])),
                area_m2=_r(footprints[o.instance_id].area),
                min_z=_r(bounds[o.instance_id][0][2]),
                max_z=_r(bounds[o.instance_id][1][2]),
                door_state=o.door.state if o.door else None,
                blocks=o.instance_id in blocking_ids,
            )
            for o in objects
        ],
        navigable_area_m2=_r(float(np.count_nonzero(navigable)) * cell),
        regions=[Region(region_id=k, area_m2=_r(n * cell), rooms=region_rooms[k])
                 for k, n in enumerate(reach.region_cells, start=1)],
        main_region=reach.main_region,
        rooms=[
            RoomReach(
                room_id=r.id,
                type=r.type,
                navigable_area_m2=_r(reach.room_cells[r.id] * cell),
                regions=list(reach.room_regions[r.id]),
                reachable=reach.room_reachable(r.id),
                unreachable_area_m2=_r(reach.unreachable_cells(r.id) * cell),
                reachable_rooms=list(reach.reachable_from(r.id)),
            )
            for r in spec.rooms
        ],
        all_rooms_connected=reach.all_rooms_connected(),
    )
    return Topdown(
        grid=grid,
        instance=instance,
        category=category,
        occupancy=occupied.astype(np.uint8),
        navigable=navigable.astype(np.uint8),
        region=reach.labels,
        categories=categories,
        semantic=semantic,
        footprints=footprints,
        passages=passages,
    )


def scene_grid(scene: LoadedScene, resolution: float) -> Grid:
    """A grid covering every mesh and room of the scene: at least the map's (ConfigError over the cell budget)."""
    boxes = [m.bounds[:, :2] for m in scene.meshes.values()]
    boxes += [np.array([np.min(r.polygon, axis=0), np.max(r.polygon, axis=0)]) for r in scene.spec.rooms]
    lo, hi = np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)
    try:
        return Grid.covering(lo, hi, resolution, margin=2 * resolution)
    except ConfigError as err:
        raise ConfigError(err.detail, path=scene.source_dir, field=err.field) from None


def floor_plan(scene: LoadedScene, footprints: dict[int, BaseGeometry], wall_gap: float) -> BaseGeometry:
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


def paint_instances(objects, footprints: dict[int, BaseGeometry], bounds: dict[int, np.ndarray], grid: Grid,
                    z_lo: float, z_hi: float) -> np.ndarray:
    """[H, W] int32 instance id per cell: footprints painted floor first, things outside the band next,
    then the rest from low to high (a TV over its stand), then walls, then the doors and windows set in
    them. Ceilings are left out: they would cover everything.
    """

    def order(o) -> tuple:
        lo, hi = bounds[o.instance_id][0][2], bounds[o.instance_id][1][2]
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
    for o in sorted((o for o in objects if o.kind != "ceiling"), key=order):
        out[polygon_mask(footprints[o.instance_id], grid, touch=o.kind in THIN_KINDS)] = o.instance_id
    return out


def _stack(items: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Concatenate per-object (tris [F, 3, 3], part [F]) into tris, globally unique part ids, owner index."""
    if not items:
        return np.zeros((0, 3, 3)), np.zeros(0, np.int64), np.zeros(0, np.int64)
    offsets = np.cumsum([0] + [int(p.max()) + 1 if len(p) else 0 for _, p in items[:-1]])
    tris = np.concatenate([t for t, _ in items])
    part = np.concatenate([p + off for (_, p), off in zip(items, offsets)])
    owner = np.concatenate([np.full(len(t), i) for i, (t, _) in enumerate(items)])
    return tris, part, owner


def _room_of(fp: BaseGeometry, rooms) -> str | None:
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
