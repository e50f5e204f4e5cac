"""One scene's export, computed whole: convex colliders per object, the USD layers (3DGS, colliders, semantics),
the MuJoCo MJCF and the collider index, with the measured quality of the colliders."""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from sagebench import ui
from sagebench.collider_export.coacd_cache import PartCache, coacd_version
from sagebench.collider_export.convex import hull_part
from sagebench.collider_export.decompose import (MeshColliders, decompose_meshes, mode_passes, plan_pieces,
                                                 tolerance_cause)
from sagebench.collider_export.free_floor import FloorMap, check_free_floor
from sagebench.collider_export.methods import UNSHAPING
from sagebench.collider_export.door_gap import clear_floor
from sagebench.collider_export.mjcf_writer import MjcfBody, mjcf_model, room_lights, scene_body
from sagebench.collider_export.pieces import Piece
from sagebench.collider_export.quality import ColliderQuality, measure_objects
from sagebench.collider_export.usd_writer import StageObject, prim_name, stage_files, usdz_package
from sagebench.errors import DataError
from sagebench.fileio import dumps_json
from sagebench.render.gaussians import Gaussians, mean_colour
from sagebench.run_layout import COLLIDERS, COLLIDERS_INDEX, GAUSSIANS, MJCF, NUREC, SAGE, USD, USDZ
from sagebench.scene.loader import SCENE_FILE, LoadedScene, door_pose, read_mesh, resolve_mesh_path
from sagebench.settings.export_usd import ColliderSettings, ExportConfig


@dataclass(frozen=True)
class ExportResult:
    scene_id: str
    out_dir: Path  # RUN/scenes/<scene_id>, the normalised scene exported
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


@dataclass(frozen=True)
class SceneExport:
    """Everything export-usd writes for one scene, computed before the first byte is written."""

    result: ExportResult
    colliders: dict[str, bytes]  # under colliders/: each part as STL (world frame), and colliders.json
    usd: dict[str, bytes]  # every USD file by its path in the scene directory, each before those referencing it
    mjcf: str


def build_export(scene: LoadedScene, gaussians: Gaussians | None, floor: FloorMap | None, *,
                 band: tuple[float, float], config: ExportConfig, cache: PartCache) -> SceneExport:
    """Colliders, USD layers and MJCF of a normalised scene (RUN/scenes/<id>, loaded) and its Gaussians (None when
    the scene has no gaussians.ply: the stage then has colliders and semantics only); `band` is the agent's (world
    z: floor + its clearance .. floor + its height) that the colliders are judged in; colliders that cover the
    free floor of `floor` (build-scene's occupancy) beyond the tolerance are refused (free_floor). Nothing is
    written."""
    spec = scene.spec
    per_object = None if gaussians is None else split_gaussians(gaussians, scene)
    nurec = config.gaussians == "nurec"
    local = local_meshes(scene)
    colliders = decompose_meshes(local, config.colliders, cache=cache, workers=config.workers,
                                 convex_tolerance=config.convex_tolerance, band=band)
    quality = _measure_objects(scene, local, colliders, band, config.workers)
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
        parts = mc.parts if obj.door is None else clear_floor(mc.parts, matrix, spec.floor_height)
        so = StageObject(
            instance_id=obj.instance_id, category=obj.category, kind=obj.kind, matrix=matrix, parts=parts,
            room_id=obj.room_id, room_type=rooms.get(obj.room_id), attributes=obj.attributes, door=obj.door,
            gaussians=None if per_object is None or nurec else per_object.get(obj.instance_id),
        )
        objects.append(so)
        name = prim_name(so)
        part_files = []
        for i, part in enumerate(parts):
            world = hull_part(trimesh.transform_points(part.vertices, matrix))
            rel = f"{name}/part_{i:03d}.stl"
            files[rel] = trimesh.Trimesh(world.vertices, world.faces, process=False).export(file_type="stl")
            part_files.append(rel)
        bodies.append(scene_body(so, part_files, None if per_object is None or obj.instance_id not in per_object
                                 else mean_colour(per_object[obj.instance_id])))
        index.append(_index_entry(obj.instance_id, name, obj.mesh, part_files, mc, quality.get(obj.instance_id)))
    names = {o.instance_id: prim_name(o) for o in objects}
    causes = {o.instance_id: tolerance_cause(o.mesh, colliders[o.mesh], config.colliders) for o in spec.objects}
    if floor is not None:
        check_free_floor([(names[o.instance_id], matrices[o.instance_id], colliders[o.mesh].parts,
                           quality[o.instance_id].band_error_cm, causes[o.instance_id])
                          for o in spec.objects if o.instance_id in quality],
                         band, floor, config.colliders.band_tolerance_cm)
    mjcf = mjcf_model(spec.scene_id, bodies, meshes=files, meshdir=COLLIDERS, floor_height=spec.floor_height,
                      lights=room_lights(scene))
    usd = _usd_files(spec.scene_id, objects, gaussians, None if per_object is None or nurec else per_object.get(0),
                     config, mjcf.exclude)
    shaping = config.model_dump(exclude={"workers": True, "colliders": set(UNSHAPING)})  # what the files depend on
    files[COLLIDERS_INDEX] = dumps_json({
        "scene_id": spec.scene_id, "coacd_version": coacd_version(), "config": shaping,
        "frame": "world", "objects": index,
    }).encode()
    pieces = [p for mc in colliders.values() for p in mc.pieces]
    _warn_over_tolerance(names, causes, quality, config.colliders)
    worst = max(((names[i], q) for i, q in quality.items()), key=lambda nq: nq[1].band_error_cm, default=None)
    result = ExportResult(
        scene_id=spec.scene_id, out_dir=scene.source_dir, objects=len(objects),
        parts=sum(len(colliders[o.mesh].parts) for o in spec.objects),
        exact_parts=sum(colliders[o.mesh].exact_parts for o in spec.objects),
        methods=dict(Counter(p.method for p in pieces)), cached_pieces=sum(p.cached for p in pieces),
        gaussians=0 if per_object is None else sum(g.count for g in per_object.values()), worst=worst,
    )
    return SceneExport(result, files, usd, mjcf.xml)


def _usd_files(scene_id: str, objects: list[StageObject], whole: Gaussians | None, background: Gaussians | None,
               config: ExportConfig, filtered: Sequence[tuple[str, str]]) -> dict[str, bytes]:
    """Every USD file of the export by its path in the scene directory, each before those referencing it."""
    from sagebench.collider_export.sage_layout import sage_files
    from sagebench.splats.nurec import nurec_usdz

    nurec = config.gaussians == "nurec" and whole is not None
    out = {NUREC: nurec_usdz(whole, Path(NUREC).stem)} if nurec else {}
    out.update(stage_files(scene_id, objects, background, nurec=NUREC if nurec else None, filtered=filtered))
    if config.usdz:
        out[USDZ] = usdz_package(out)
    if config.layout == "sage":
        if whole is None:
            raise DataError(f"--layout sage needs the scene's Gaussians ({GAUSSIANS}): run build-scene again")
        out.update({f"{SAGE}/{name}": data for name, data in sage_files(scene_id, objects, f"../{NUREC}").items()})
    return out


def plan_scene_pieces(scene: LoadedScene, config: ExportConfig,
                      cache: PartCache) -> list[tuple[Piece, ColliderSettings]]:
    """The concave pieces build_export would decompose for the scene, each with the settings of its pass
    (quality's balanced pass included); so a run can spread them over its executor and export the scene from the
    cache (the meshes' splits are cached for the export too)."""
    local = local_meshes(scene)
    return [(piece, colliders) for colliders in mode_passes(config.colliders)
            for piece in plan_pieces(local, colliders, cache=cache, convex_tolerance=config.convex_tolerance).jobs]


def _measure_objects(scene: LoadedScene, local: dict[str, tuple[np.ndarray, np.ndarray]],
                     colliders: dict[str, MeshColliders], band: tuple[float, float],
                     workers: int) -> dict[int, ColliderQuality]:
    """Quality of the objects whose colliders have decomposed or merged pieces (exact convex pieces are their own
    collider)."""
    placed = [(o.instance_id, o.mesh, o.transform.as_matrix() if o.door is None
               else door_pose(o.door) @ o.transform.as_matrix()) for o in scene.spec.objects
              if colliders[o.mesh].pieces or colliders[o.mesh].merged]
    return measure_objects(placed, local, {name: mc.parts for name, mc in colliders.items()}, band, workers=workers)


def _warn_over_tolerance(names: dict[int, str], causes: dict[int, str], quality: dict[int, ColliderQuality],
                         settings: ColliderSettings) -> None:
    """One warning per object whose colliders miss its agent-band footprint by more than the tolerance, with
    why (decompose.tolerance_cause: its methods, or the part budget)."""
    for instance_id, q in sorted(quality.items()):
        if q.band_error_cm > settings.band_tolerance_cm:
            ui.warn(f"{names[instance_id]}: colliders {q.band_error_cm:.1f} cm off in the agent band, over the "
                    f"{settings.band_tolerance_cm:g} cm tolerance: {causes[instance_id]}")


def local_meshes(scene: LoadedScene) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each mesh file of the scene once, in its own frame (so one asset decomposes once for all its uses)."""
    spec_path = scene.source_dir / SCENE_FILE
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for i, obj in enumerate(scene.spec.objects):
        if obj.mesh not in out:
            field = f"objects[{i}].mesh"
            mesh = read_mesh(resolve_mesh_path(scene.source_dir, obj.mesh, spec_path, field), spec_path, field)
            out[obj.mesh] = (np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64))
    return out


def split_gaussians(g: Gaussians, scene: LoadedScene) -> dict[int, Gaussians]:
    """The scene's Gaussians grouped by instance id (0: background); an id that is no object of the scene is a
    DataError on its gaussians.ply."""
    path = scene.source_dir / GAUSSIANS
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
