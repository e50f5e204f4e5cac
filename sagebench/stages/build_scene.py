"""`build-scene`: a scene directory -> RUN/scenes/<scene_id>/ with the normalised scene and its top-down maps.

Writes scene.json + meshes (normalised, loadable with `load_scene`), topdown.npz, semantic_map.json,
topdown.png and gaussians.ply (3DGS with instance ids), all at once (a staged directory renamed into place).
"""

from __future__ import annotations

import io
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import shapely
from pydantic import BaseModel, ConfigDict, Field, model_validator
from shapely.geometry.base import BaseGeometry

from sagebench.config import AgentConfig, from_options
from sagebench.errors import SceneError
from sagebench.fileio import dumps_json, staged_dir, write_bytes
from sagebench.scene.loader import LoadedScene, load_scene, write_normalised_scene
from sagebench.splats.prune import PruneReport
from sagebench.splats.scene import SplatConfig
from sagebench.topdown.footprints import footprint, mesh_parts
from sagebench.topdown.occupancy import band_occupancy, clip_to_band, inflate
from sagebench.topdown.raster import Grid, polygon_mask
from sagebench.topdown.regions import reachability
from sagebench.topdown.semantic_map import MapInstance, MultiPolygon, Region, RoomReach, SemanticMap
from sagebench.ui import track

NOT_BLOCKING_KINDS = frozenset({"floor", "ceiling"})  # walkable surfaces and what is above every head
THIN_KINDS = frozenset({"door", "window"})  # painted where they touch a cell, so a 4 cm leaf shows


class TopdownConfig(BaseModel):
    """Settings of build-scene; the CLI maps its options onto these fields."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    resolution: float = Field(default=0.05, gt=0, le=1.0, description="Grid cell side, m.")
    band_min: float = Field(default=0.05, ge=0, description="Lowest blocking height above the floor, m.")
    band_max: float = Field(default=1.2, gt=0, description="Highest blocking height above the floor, m.")
    sample_density: float = Field(default=400.0, gt=0, description="Footprint surface samples per m^2.")
    wall_gap: float = Field(
        default=0.3, ge=0, description="Room floor polygons closer than this join across the wall between them, m."
    )
    seed: int = Field(default=0, description="Seed of the footprint surface and Gaussian sampling.")
    agent: AgentConfig = AgentConfig()
    splats: SplatConfig = SplatConfig()

    @model_validator(mode="after")
    def _band_order(self) -> TopdownConfig:
        if self.band_max <= self.band_min:
            raise ValueError(f"band_max ({self.band_max}) must be above band_min ({self.band_min})")
        return self


_OPTIONS = {"agent.radius": "agent_radius", "splats.prune": "prune", "splats.object_density": "object_density",
            "splats.structure_density": "structure_density"}


def make_config(*, agent_radius: float | None = None, prune: float | None = None,
                object_density: float | None = None, structure_density: float | None = None,
                **fields: object) -> TopdownConfig:
    """A TopdownConfig from the options given (None = keep the default); a bad value is a ConfigError."""
    given = {**fields, "agent": {"radius": agent_radius},
             "splats": {"prune": prune, "object_density": object_density, "structure_density": structure_density}}
    return from_options(TopdownConfig, given, lambda loc: _OPTIONS.get(loc, loc))


@dataclass(frozen=True)
class BuildSceneResult:
    scene_id: str
    out_dir: Path  # RUN/scenes/<scene_id>
    shape: tuple[int, int]  # (H, W) cells
    resolution: float
    navigable_area_m2: float
    rooms: int
    rooms_in_largest_group: int  # rooms mutually reachable in the best-connected group
    all_rooms_connected: bool
    gaussians: int
    pruned: PruneReport | None

    def summary(self) -> str:
        h, w = self.shape
        prune = "" if self.pruned is None else (
            f" (pruned {self.pruned.fraction:.0%} of {self.pruned.count_before}: held-out PSNR "
            f"{self.pruned.psnr_db:.1f} dB)")
        return (
            f"build-scene {self.scene_id}: map {w}x{h} cells at {self.resolution:g} m, "
            f"navigable {self.navigable_area_m2:.1f} m^2, {self.rooms_in_largest_group}/{self.rooms} rooms "
            f"reachable from each other, {self.gaussians} Gaussians{prune} -> {self.out_dir}"
        )


@dataclass(frozen=True)
class Topdown:
    """Everything build-scene computes, before it is written."""

    grid: Grid
    instance: np.ndarray  # [H, W] int32, instance id per cell, 0 background
    category: np.ndarray  # [H, W] int16, category id per cell (index into categories), 0 background
    occupancy: np.ndarray  # [H, W] uint8, 1 blocked, 0 free
    navigable: np.ndarray  # [H, W] uint8, 1 where the agent's centre may stand
    region: np.ndarray  # [H, W] int32, connected navigable region id, 0 elsewhere
    categories: list[str]
    semantic: SemanticMap
    footprints: dict[int, BaseGeometry]  # instance id -> footprint, world m


def build_scene(scene_dir: Path, run_dir: Path, config: TopdownConfig | None = None) -> BuildSceneResult:
    """Load `scene_dir`, compute its top-down maps and Gaussians and write RUN/scenes/<scene_id>/ atomically."""
    from sagebench.splats.ply import write_ply
    from sagebench.splats.scene import scene_gaussians
    from sagebench.topdown.render_png import render_topdown

    config = config or TopdownConfig()
    scene = load_scene(scene_dir)
    td = compute_topdown(scene, config)
    png = render_topdown(td)
    gaussians, pruned = scene_gaussians(scene, config.splats, seed=config.seed, agent=config.agent)
    out = Path(run_dir) / "scenes" / scene.spec.scene_id
    with staged_dir(out) as tmp:
        write_normalised_scene(scene, tmp)
        write_bytes(tmp / "topdown.npz", _npz_bytes({
            "instance": td.instance,
            "category": td.category,
            "occupancy": td.occupancy,
            "navigable": td.navigable,
            "region": td.region,
            "resolution": np.float64(td.grid.resolution),
            "origin": np.asarray(td.grid.origin, dtype=np.float64),
            "category_names": np.asarray(td.categories, dtype=np.str_),
        }))
        write_bytes(tmp / "semantic_map.json", dumps_json(td.semantic.model_dump(mode="json")).encode())
        write_bytes(tmp / "topdown.png", png)
        write_ply(tmp / "gaussians.ply", gaussians)
    best = max((len(r.reachable_rooms) + 1 for r in td.semantic.rooms if r.regions), default=0)
    return BuildSceneResult(
        scene_id=scene.spec.scene_id,
        out_dir=out,
        shape=td.grid.shape,
        resolution=td.grid.resolution,
        navigable_area_m2=td.semantic.navigable_area_m2,
        rooms=len(scene.spec.rooms),
        rooms_in_largest_group=best,
        all_rooms_connected=td.semantic.all_rooms_connected,
        gaussians=gaussians.count,
        pruned=pruned,
    )


def compute_topdown(scene: LoadedScene, config: TopdownConfig) -> Topdown:
    """The maps and the semantic report of a loaded scene (no I/O)."""
    spec = scene.spec
    res = config.resolution
    z_lo, z_hi = spec.floor_height + config.band_min, spec.floor_height + config.band_max
    objects = spec.objects
    parts = {o.instance_id: mesh_parts(scene.meshes[o.instance_id]) for o in objects}
    footprints: dict[int, BaseGeometry] = {}
    for o in track(objects, "footprints"):
        tris, part = parts[o.instance_id]
        rng = np.random.default_rng([config.seed, o.instance_id])
        fp = footprint(tris, part, config.sample_density, rng, min_width=res)
        footprints[o.instance_id] = fp.simplify(res / 10)  # drops the near-collinear sample corners

    plan = floor_plan(scene, footprints, config.wall_gap)
    blockers = [o for o in objects if o.kind not in NOT_BLOCKING_KINDS]
    los = [plan.bounds[:2]] + [scene.meshes[o.instance_id].bounds[0][:2] for o in blockers]
    his = [plan.bounds[2:]] + [scene.meshes[o.instance_id].bounds[1][:2] for o in blockers]
    grid = Grid.covering(np.min(los, axis=0), np.max(his, axis=0), res, margin=2 * res)

    tris, part, owner = _stack([parts[o.instance_id] for o in blockers])
    occupied = band_occupancy(tris, part, grid, z_lo, z_hi) | ~polygon_mask(plan, grid)
    navigable = inflate(occupied, config.agent.radius, res)
    _, src = clip_to_band(tris, z_lo, z_hi)
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
        navigable_area_m2=_r(float(navigable.sum()) * cell),
        regions=[Region(region_id=k, area_m2=_r(n * cell), rooms=region_rooms[k])
                 for k, n in enumerate(reach.region_cells, start=1)],
        rooms=[
            RoomReach(
                room_id=r.id,
                type=r.type,
                navigable_area_m2=_r(float((navigable & room_masks[r.id]).sum()) * cell),
                regions=list(reach.room_regions[r.id]),
                reachable_rooms=list(reach.reachable[r.id]),
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
    )


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
        raise SceneError("no rooms and no floor meshes: cannot tell where the floor is", path=scene.source_dir / "scene.json",
                         field="rooms")
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
    """Round to 0.1 mm: stable text, far below the grid's resolution."""
    return round(float(v), 4)


def _npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    """An .npz (np.load reads it) with fixed zip timestamps, so equal arrays give equal bytes."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name, arr in arrays.items():
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            data = io.BytesIO()
            np.lib.format.write_array(data, np.asarray(arr), allow_pickle=False)
            zf.writestr(info, data.getvalue())
    return buf.getvalue()
