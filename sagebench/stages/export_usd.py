"""`export-usd`: RUN/scenes/<id>/ -> colliders/ (convex parts), scene.usda + geometry.usdc (3DGS, colliders,
semantics), scene.xml, and with --usdz scene.usdz.

Reads the normalised scene (scene.json + meshes) and gaussians.ply that build-scene wrote. Writes
colliders/<category>_<instance_id>/part_NNN.stl (world frame) and colliders/colliders.json, then
geometry.usdc, scene.usda (which references it), scene.usdz and scene.xml; all are computed before the
first byte is written.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh
from pydantic import BaseModel, ConfigDict, Field

from sagebench import ui
from sagebench.collider_export.coacd_cache import PartCache, PieceResult, coacd_version
from sagebench.collider_export.convex import hull_part
from sagebench.collider_export.decompose import (MeshColliders, decompose_meshes, mode_passes, plan_pieces,
                                                 tolerance_cause)
from sagebench.collider_export.pieces import Piece, decompose_pieces
from sagebench.collider_export.free_floor import FloorMap, check_free_floor
from sagebench.collider_export.methods import UNSHAPING, ColliderSettings, agent_band
from sagebench.collider_export.mjcf_writer import MjcfBody, mjcf_text, scene_body
from sagebench.collider_export.quality import ColliderQuality, measure_objects
from sagebench.collider_export.usd_writer import StageObject, prim_name, stage_files, usdz_package
from sagebench.config import from_options
from sagebench.errors import DataError
from sagebench.fileio import dumps_json, staged_dir, write_bytes, write_text
from sagebench.render.gaussians import Gaussians
from sagebench.run_layout import (COLLIDERS, COLLIDERS_INDEX, GAUSSIANS, MJCF, SCENES, TOPDOWN, USD, USD_GEOMETRY,
                                  USDZ)
from sagebench.scene.loader import SCENE_FILE, LoadedScene, door_pose, load_scene, read_mesh, resolve_mesh_path
from sagebench.topdown.grid_file import read_topdown_grids



class ExportConfig(BaseModel):
    """Settings of export-usd; the CLI maps its options onto these fields (workers never change outputs)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    colliders: ColliderSettings = ColliderSettings()
    convex_tolerance: float = Field(
        default=0.002, gt=0, lt=1, description="A closed piece within this relative volume of its hull is convex."
    )
    workers: int = Field(default=1, ge=1,
                         description="Processes splitting meshes, decomposing pieces and measuring colliders.")
    usdz: bool = Field(default=False, description="Also package the stage and its layers as scene.usdz.")


# export-usd's options and the ExportConfig fields they set (their defaults and error names come from here)
OPTIONS = {"--colliders": "colliders.mode", "--max-parts": "colliders.max_parts",
           "--piece-limit": "colliders.piece_limit_s", "--band-tolerance": "colliders.band_tolerance_cm",
           "--coacd-threshold": "colliders.coacd.threshold",
           "--coacd-max-faces": "colliders.coacd_max_faces", "--coacd-max-hulls": "colliders.coacd.max_convex_hull",
           "--coacd-preprocess": "colliders.coacd.preprocess_mode", "--workers": "workers", "--usdz": "usdz"}


def make_config(
    *, colliders: str | None = None, max_parts: int | None = None, piece_limit: float | None = None,
    band_tolerance: float | None = None, coacd_threshold: float | None = None, coacd_max_faces: int | None = None,
    coacd_max_hulls: int | None = None, coacd_preprocess: str | None = None, workers: int | None = None,
    usdz: bool | None = None,
) -> ExportConfig:
    """An ExportConfig from the options given (None = keep the default); a bad value is a ConfigError."""
    coacd = {"threshold": coacd_threshold, "max_convex_hull": coacd_max_hulls, "preprocess_mode": coacd_preprocess}
    given = {"mode": colliders, "max_parts": max_parts, "piece_limit_s": piece_limit,
             "band_tolerance_cm": band_tolerance, "coacd_max_faces": coacd_max_faces, "coacd": coacd}
    return from_options(ExportConfig, {"colliders": given, "workers": workers, "usdz": usdz}, OPTIONS)


def default_cache_dir() -> Path:
    import platformdirs

    return Path(platformdirs.user_cache_dir("sagebench"))


@dataclass(frozen=True)
class ExportResult:
    scene_id: str
    out_dir: Path  # RUN/scenes/<scene_id>
    objects: int
    parts: int
    exact_parts: int  # parts that are convex pieces of the meshes themselves
    methods: dict[str, int]  # concave pieces (or whole meshes over the part budget) per method that made them
    cached_pieces: int  # of those, read back from the cache
    gaussians: int  # Gaussians written into the stage
    worst: tuple[str, ColliderQuality] | None = None  # the measured object with the largest band error

    def line(self) -> str:
        made = ", ".join(f"{m} {n}" for m, n in sorted(self.methods.items())) or "none"
        return (f"{self.scene_id}: {self.objects} objects, {self.parts} collider parts ({self.exact_parts} exact; "
                f"pieces: {made}; {self.cached_pieces} cached), "
                f"{self.gaussians} Gaussians{self.quality_text()} -> {self.out_dir / USD}, {self.out_dir / MJCF}")

    def quality_text(self) -> str:
        if self.worst is None:
            return ""
        name, q = self.worst
        return (f", worst collider {name}: agent band {q.band_over_cm:.1f} cm over / {q.band_under_cm:.1f} cm under, "
                f"surface {q.to_source_max_cm:.1f} / {q.from_source_max_cm:.1f} cm")


def scene_dirs(run_dir: Path, scene_id: str | None) -> list[Path]:
    """RUN/scenes/<id> for the scene asked for, or every scene of the run (sorted)."""
    scenes = Path(run_dir) / SCENES
    if scene_id is not None:
        one = scenes / scene_id
        if not (one / SCENE_FILE).is_file():
            raise DataError(f"no scene {scene_id!r} in this run (run build-scene first)", path=scenes)
        return [one]
    found = sorted(p.parent for p in scenes.glob(f"*/{SCENE_FILE}"))
    if not found:
        raise DataError("no scenes/<id>/scene.json in this run directory (run build-scene first)", path=run_dir)
    return found


def export_usd(
    run_dir: Path, *, scene_id: str | None = None, config: ExportConfig = ExportConfig(), cache_dir: Path | None = None
) -> list[ExportResult]:
    """Export every scene of the run (or `scene_id`); CoACD results are cached in `cache_dir`
    (default: the user cache directory)."""
    cache = part_cache(cache_dir)
    return [export_scene(d, config=config, cache=cache) for d in scene_dirs(run_dir, scene_id)]


def part_cache(cache_dir: Path | None) -> PartCache:
    """The piece cache in `cache_dir`, or in the user cache directory when None."""
    return PartCache(default_cache_dir() if cache_dir is None else cache_dir)


def scene_pieces(run_dir: Path, scene_id: str, config: ExportConfig,
                 cache: PartCache) -> tuple[list[tuple[Piece, ColliderSettings]], float]:
    """The concave pieces export_scene would decompose for the scene, each with the settings of its pass
    (quality's balanced pass included), and the floor height they are measured from; so a run can spread them
    over its executor and export the scene from the cache (the meshes' splits are cached for the export too)."""
    (scene_dir,) = scene_dirs(run_dir, scene_id)
    scene = load_scene(scene_dir)
    local = _local_meshes(scene)
    jobs = [(piece, colliders) for colliders in mode_passes(config.colliders)
            for piece in plan_pieces(local, colliders, cache=cache, convex_tolerance=config.convex_tolerance).jobs]
    return jobs, scene.spec.floor_height


def decompose_piece(piece: Piece, colliders: ColliderSettings, floor_height: float,
                    cache_dir: Path | None) -> PieceResult:
    """One piece as export_scene's pass with `colliders` makes it (methods, safety limit, cache), without
    progress lines."""
    (result,) = decompose_pieces([piece], colliders, cache=part_cache(cache_dir), floor_height=floor_height,
                                 progress=False)
    return result


def export_scene(scene_dir: Path, *, config: ExportConfig, cache: PartCache) -> ExportResult:
    scene = load_scene(scene_dir)
    spec = scene.spec
    local = _local_meshes(scene)
    colliders = decompose_meshes(local, config.colliders, cache=cache, workers=config.workers,
                                 convex_tolerance=config.convex_tolerance, floor_height=spec.floor_height)
    quality = _measure_objects(scene, local, colliders, config.workers)
    per_object = _split_gaussians(scene_dir / GAUSSIANS, scene)
    rooms = {r.id: r.type for r in spec.rooms}
    objects: list[StageObject] = []
    files: dict[str, bytes] = {}
    bodies: list[MjcfBody] = []
    index = []
    matrices: dict[int, np.ndarray] = {}
    for obj in spec.objects:
        matrix = obj.transform.as_matrix()
        if obj.door is not None:
            matrix = door_pose(obj.door) @ matrix
        matrices[obj.instance_id] = matrix
        mc = colliders[obj.mesh]
        so = StageObject(
            instance_id=obj.instance_id, category=obj.category, kind=obj.kind, matrix=matrix, parts=mc.parts,
            room_id=obj.room_id, room_type=rooms.get(obj.room_id), attributes=obj.attributes, door=obj.door,
            gaussians=None if per_object is None else per_object.get(obj.instance_id),
        )
        objects.append(so)
        name = prim_name(so)
        part_files = []
        for i, part in enumerate(mc.parts):
            world = hull_part(trimesh.transform_points(part.vertices, matrix))
            rel = f"{name}/part_{i:03d}.stl"
            files[rel] = trimesh.Trimesh(world.vertices, world.faces, process=False).export(file_type="stl")
            part_files.append(rel)
        bodies.append(scene_body(so, part_files))
        index.append(_index_entry(obj.instance_id, name, obj.mesh, part_files, mc, quality.get(obj.instance_id)))
    names = {o.instance_id: prim_name(o) for o in objects}
    causes = {o.instance_id: tolerance_cause(colliders[o.mesh], config.colliders) for o in spec.objects}
    _check_free_floor(scene_dir, spec.floor_height, [
        (names[o.instance_id], matrices[o.instance_id], colliders[o.mesh].parts, quality[o.instance_id].band_error_cm,
         causes[o.instance_id]) for o in spec.objects if o.instance_id in quality], config.colliders)
    usd = stage_files(spec.scene_id, objects, None if per_object is None else per_object.get(0))
    usdz = usdz_package(usd) if config.usdz else None
    mjcf = mjcf_text(spec.scene_id, bodies, meshes=files, meshdir=COLLIDERS, floor_height=spec.floor_height)
    shaping = config.model_dump(exclude={"workers": True, "colliders": set(UNSHAPING)})  # what the files depend on
    files[COLLIDERS_INDEX] = dumps_json({
        "scene_id": spec.scene_id, "coacd_version": coacd_version(), "config": shaping,
        "frame": "world", "objects": index,
    }).encode()
    with staged_dir(scene_dir / COLLIDERS) as tmp:
        for rel, data in files.items():
            write_bytes(tmp / rel, data)
    for name in (USD_GEOMETRY, USD):  # the root last: it references the crate layer
        write_bytes(scene_dir / name, usd[name])
    if usdz is not None:
        write_bytes(scene_dir / USDZ, usdz)
    else:
        (scene_dir / USDZ).unlink(missing_ok=True)  # a previous export's, which this stage no longer matches
    write_text(scene_dir / MJCF, mjcf)
    pieces = [p for mc in colliders.values() for p in mc.pieces]
    _warn_over_tolerance(names, causes, quality, config.colliders)
    worst = max(((names[i], q) for i, q in quality.items()), key=lambda nq: nq[1].band_error_cm, default=None)
    return ExportResult(
        scene_id=spec.scene_id, out_dir=scene_dir, objects=len(objects),
        parts=sum(len(colliders[o.mesh].parts) for o in spec.objects),
        exact_parts=sum(colliders[o.mesh].exact_parts for o in spec.objects),
        methods=dict(Counter(p.method for p in pieces)), cached_pieces=sum(p.cached for p in pieces),
        gaussians=0 if per_object is None else sum(g.count for g in per_object.values()), worst=worst,
    )


def _measure_objects(scene: LoadedScene, local: dict[str, tuple[np.ndarray, np.ndarray]],
                     colliders: dict[str, MeshColliders], workers: int) -> dict[int, ColliderQuality]:
    """Quality of the objects whose colliders have decomposed or merged pieces (exact convex pieces are their own
    collider)."""
    placed = [(o.instance_id, o.mesh, o.transform.as_matrix() if o.door is None
               else door_pose(o.door) @ o.transform.as_matrix()) for o in scene.spec.objects
              if colliders[o.mesh].pieces or colliders[o.mesh].merged]
    return measure_objects(placed, local, {name: mc.parts for name, mc in colliders.items()}, scene.spec.floor_height,
                           workers=workers)


def _warn_over_tolerance(names: dict[int, str], causes: dict[int, str], quality: dict[int, ColliderQuality],
                         settings: ColliderSettings) -> None:
    """One warning per object whose colliders miss its agent-band footprint by more than the tolerance, with
    why (decompose.tolerance_cause: its methods, or the part budget)."""
    for instance_id, q in sorted(quality.items()):
        if q.band_error_cm > settings.band_tolerance_cm:
            ui.warn(f"{names[instance_id]}: colliders {q.band_error_cm:.1f} cm off in the agent band, over the "
                    f"{settings.band_tolerance_cm:g} cm tolerance: {causes[instance_id]}")


def _check_free_floor(scene_dir: Path, floor_height: float, placed: list, settings: ColliderSettings) -> None:
    """free_floor.check_free_floor against the scene's topdown.npz (build-scene's); without one (a scene
    written by other means) the band warnings are all there is."""
    if not (scene_dir / TOPDOWN).is_file():
        return
    grids = read_topdown_grids(scene_dir / TOPDOWN)
    check_free_floor(placed, agent_band(floor_height), FloorMap(grids.occupancy, grids.resolution, grids.origin),
                     settings.band_tolerance_cm)


def _local_meshes(scene: LoadedScene) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each mesh file of the scene once, in its own frame (so one asset decomposes once for all its uses)."""
    spec_path = scene.source_dir / SCENE_FILE
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for i, obj in enumerate(scene.spec.objects):
        if obj.mesh not in out:
            field = f"objects[{i}].mesh"
            mesh = read_mesh(resolve_mesh_path(scene.source_dir, obj.mesh, spec_path, field), spec_path, field)
            out[obj.mesh] = (np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64))
    return out


def _split_gaussians(path: Path, scene: LoadedScene) -> dict[int, Gaussians] | None:
    """The scene's Gaussians grouped by instance id (0: background); None without the file."""
    if not path.is_file():
        ui.warn(f"{path}: not found; the stage gets colliders and semantics but no Gaussians")
        return None
    from sagebench.splats.ply import read_ply

    g = read_ply(path)
    known = {o.instance_id for o in scene.spec.objects}
    stray = sorted(set(np.unique(g.instance_id).tolist()) - known - {0})
    if stray:
        raise DataError(f"instance_id {stray[0]} is not an object of {SCENE_FILE}", path=path, field="instance_id")
    order = np.argsort(g.instance_id, kind="stable")
    ids, starts = np.unique(g.instance_id[order], return_index=True)
    ends = np.append(starts[1:], len(order))
    return {int(i): g.take(order[s:e]) for i, s, e in zip(ids, starts, ends)}


def _index_entry(instance_id: int, name: str, mesh: str, part_files: list[str], mc: MeshColliders,
                 quality: ColliderQuality | None) -> dict:
    return {
        "instance_id": instance_id, "name": name, "mesh": mesh, "parts": part_files, "exact_parts": mc.exact_parts,
        "concave_pieces": [{"cache_key": p.key, "method": p.method, "parts": len(p.parts),
                            "band_error_cm": round(p.band_error_cm, 3)} for p in mc.pieces],
        "whole_mesh": mc.whole, "merged_parts": mc.merged,
        "quality": None if quality is None else quality.as_dict(),
    }
