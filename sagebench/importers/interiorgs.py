"""An InteriorGS scene folder -> a sagebench scene (scene.json, meshes, gaussians.ply with instance ids).

- Gaussians are read from the PLY (compressed or INRIA layout); the dataset's frame is already metres, Z up.
  Floaters (importers/interiorgs_evidence.py) take no part in the geometry; gaussians.ply keeps every Gaussian
  of the source, in its order, floaters with id 0 (background).
- Each Gaussian gets the instance of the tightest object box that holds it, unless it lies on a wall, floor
  or ceiling (within `structure_margin`): a floor's Gaussians under a sofa belong to the floor. Gaussians in
  no box go to the structure within `structure_reach`, else stay background (id 0).
- Rooms, walls (openings cut), floor and ceiling slabs come from structure.json; a DOOR opening with a door
  label in it becomes a door whose leaf, state and swing are read off the label's box.
- Every object's surface is made from its own Gaussians (splat_geometry.surface); a label whose box holds no
  Gaussians is left out with a warning. With a SAGE-3D collision USD, its meshes replace the surfaces of the
  objects they match.
- What no label explains, background Gaussians dense enough in the agent's band and cells occupancy.png marks
  occupied that nothing imported covers, becomes "unlabelled" obstacles (importers/interiorgs_evidence.py),
  numbered after the ceilings; more of their floor than `max_unlabelled_area` is a warning.
- How far the Gaussians on walls and floor scatter about their planes (importers/interiorgs_evidence.py) is
  reported; more than `max_surface_noise` is a warning.
- The shipped occupancy.png is compared with the imported geometry's own height-band occupancy.
- scene.json's `sage_offset` is where SAGE-3D's 3D frame of the scene lies (sagebench.importers.sage_frame).

Instance ids: labelled objects first, in labels.json order (so "<category>_<k>", k counting a category's objects
in id order, names the same object as SAGE-3D's item ids), then walls, floors and ceilings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import shapely
import trimesh
from pydantic import ValidationError

from sagebench import ui
from sagebench.errors import ConfigError, DataError, first_error
from sagebench.fileio import dumps_json, write_bytes
from sagebench.importers.boxes import BoxError, OrientedBox, box_from_corners, box_owner
from sagebench.importers.config import OCCUPANCY_PICTURE, REPORT_FILE
from sagebench.importers.interiorgs_files import (
    LABELS, STRUCTURE, InteriorGSFolder, WallSegment, read_folder,
)
from sagebench.importers.interiorgs_evidence import Unlabelled, floaters, surface_noise, unlabelled_obstacles
from sagebench.importers.interiorgs_occupancy import band_blocked, compare_occupancy
from sagebench.importers.interiorgs_structure import (
    DEFAULT_CEILING_M, SLAB_M, DoorPose, Opening, box_mesh, door_pose, openings_on, room_polygon, room_type, slab,
    snake, wall_pieces,
)
from sagebench.importers.sage_frame import sage_offset
from sagebench.render.gaussians import Gaussians
from sagebench.run_layout import SCENE_FILE
from sagebench.scene.model import UNLABELLED, Door, Room, SceneObject, SceneSpec
from sagebench.settings.build_scene import BuildSceneConfig
from sagebench.settings.import_interiorgs import InteriorGSConfig
from sagebench.splat_geometry.surface import (
    MAX_VOXELS, SurfaceSettings, gaussian_covariances, gaussian_points, grid_voxels, object_surface,
)
from sagebench.splats.ply import read_ply, write_ply
from sagebench.splats.scene import TRAINED_FILES

STRUCTURAL_LABELS = frozenset({"wall", "floor", "ceiling"})  # built from structure.json, not from their boxes
DOOR_REACH_M = 0.2  # a door label belongs to a DOOR opening when its centre is within the opening's width plus this


@dataclass
class _Thing:
    """One object of the scene being made: its world mesh (a door's in its closed pose) and what scene.json says."""

    instance_id: int
    category: str
    kind: str
    mesh: trimesh.Trimesh | None = None
    posed: trimesh.Trimesh | None = None  # a door leaf as it stands (for the occupancy check)
    room_id: str | None = None
    door: Door | None = None
    pose: DoorPose | None = None
    label: int | None = None  # index into labels.json
    box: OrientedBox | None = None
    segment: WallSegment | None = None  # a wall's line
    openings: list[Opening] = field(default_factory=list)  # a wall's openings


@dataclass(frozen=True)
class ImportedScene:
    spec: SceneSpec
    meshes: dict[str, trimesh.Trimesh]  # path relative to the scene directory -> world mesh
    gaussians: Gaussians  # with instance ids
    report: dict
    picture: bytes  # occupancy.png against the imported geometry
    warnings: tuple[str, ...] = field(default=())


def import_interiorgs(src: Path, config: InteriorGSConfig = InteriorGSConfig(),
                      build: BuildSceneConfig = BuildSceneConfig(), collision_usd: Path | None = None) -> ImportedScene:
    """Read the InteriorGS folder `src` and make its sagebench scene (nothing is written)."""
    folder = read_folder(src)
    scene_id = folder.scene_id
    warnings: list[str] = []
    rooms = _rooms(folder)
    walls, pieces, piece_wall, matched_holes = _walls(folder)
    slabs = _slabs(folder, rooms)
    objects = _labelled(folder, rooms)
    _check_voxel_budget(folder, objects, config.voxel)
    warnings += _renamed_ids(folder) + _openings_on_no_wall(folder, matched_holes)
    gaussians = read_ply(folder.ply)
    if gaussians.count == 0:
        raise DataError("holds no Gaussians", path=folder.ply, field="vertex")
    stray = floaters(gaussians.means, config.floater_cell, config.floater_neighbours)
    noise = surface_noise(gaussians.means[~stray], pieces, shapely.union_all(rooms), [t.box for t in objects],
                          config.box_margin, config.structure_reach)
    noise = None if noise is None else round(noise, 4)  # m, as reported
    _match_doors(objects, walls, folder, rooms)
    things = [*objects, *walls, *slabs]
    for k, t in enumerate(things, start=1):
        t.instance_id = k
    structure = _StructureIndex(pieces, np.array([walls[i].instance_id for i in piece_wall], dtype=np.int64),
                                rooms, slabs)
    ids, shares = _assign(gaussians.means, stray, objects, structure, config)
    band = build.agent.band  # the floor is z = 0
    settings = SurfaceSettings(config.voxel, config.min_opacity, config.max_parts, band)
    shape_only = replace(gaussians, sh=gaussians.sh[:, :1])  # a view: the surfaces need no SH, take() copies none
    empty = _surfaces(shape_only, ids, objects, settings)
    if empty:
        warnings.append(f"{len(empty)} labels hold no Gaussians and are left out: labels.json "
                        f"{', '.join(f'[{i}]' for i in empty[:10])}{' ...' if len(empty) > 10 else ''}")
    collision = None
    if collision_usd is not None:
        collision = _use_collision_meshes(Path(collision_usd), [t for t in objects if t.mesh is not None])
    kept = [t for t in things if t.mesh is not None]
    blocked = band_blocked(folder.occupancy, [t.posed if t.posed is not None else t.mesh for t in kept
                                              if t.kind not in ("floor", "ceiling")], band)
    unlabelled = _unlabelled(folder, rooms, gaussians, ids, blocked, band, config, len(things) + 1)
    kept += unlabelled.things
    spec = _spec(scene_id, folder, rooms, kept, sage_offset(folder.occupancy, folder.labels))
    agreement = compare_occupancy(folder.occupancy, blocked, rooms, unlabelled.found.cells > 0)
    if agreement.iou < config.min_occupancy_iou:
        warnings.append(f"{scene_id}: occupancy.png and the imported geometry agree on {agreement.iou:.0%} of the "
                        f"free floor (IoU, under {config.min_occupancy_iou:.0%}); see {OCCUPANCY_PICTURE}")
    area = sum(unlabelled.found.areas)
    if area > config.max_unlabelled_area:
        warnings.append(f"{scene_id}: {area:.2f} m^2 of floor that no label explains (over {config.max_unlabelled_area:g}"
                        f" m^2) is blocked as unlabelled obstacles: "
                        f"{', '.join(t.category + f'_{t.instance_id}' for t in unlabelled.things)}; see "
                        f"{OCCUPANCY_PICTURE} (orange)")
    if noise is not None and noise > config.max_surface_noise:
        warnings.append(f"{scene_id}: the Gaussians on walls and floor scatter {noise * 100:.2f} cm about their planes "
                        f"(robust standard deviation, over {config.max_surface_noise * 100:g} cm): positional noise "
                        "that widens every obstacle and wall of the maps by about as much")
    for w in warnings:
        ui.warn(w)
    ids[~np.isin(ids, [t.instance_id for t in kept])] = 0  # floaters and a left-out label's Gaussians: background
    report = {
        "scene_id": scene_id,
        "gaussians": gaussians.count,
        "floaters_dropped": int(stray.sum()),
        "surface_noise_m": noise,  # importers/interiorgs_evidence.py
        "shares": shares,
        "labels": len(folder.labels),
        "objects": sum(t.label is not None for t in kept),  # labelled objects (walls, floors, ceilings aside)
        "rooms": len(rooms),
        "walls": len(walls),
        "labels_without_gaussians": empty,
        "openings": len(folder.holes),
        "openings_on_no_wall": sorted(set(range(len(folder.holes))) - matched_holes),
        "doors": {t.category + f"_{t.instance_id}": t.door.state for t in kept if t.door is not None},
        "collision_meshes": collision,
        "unlabelled": {f"unlabelled_{t.instance_id}": {"area_m2": round(a, 3), "top_m": round(top, 3)}
                       for t, a, top in zip(unlabelled.things, unlabelled.found.areas, unlabelled.found.tops)},
        "occupancy_iou": round(agreement.iou, 4),
        "sage_offset_m": list(spec.sage_offset),  # SAGE-3D's 3D frame: sagebench.importers.sage_frame
        "occupancy_free_cells": {"sagebench": agreement.free_ours, "occupancy.png": agreement.free_theirs},
        "instances": {str(t.instance_id): {"label": None if t.label is None else folder.labels[t.label].ins_id,
                                           "category": t.category} for t in kept},
    }
    with_ids = Gaussians(gaussians.means, gaussians.quats_wxyz, gaussians.log_scales, gaussians.opacity_logits,
                         gaussians.sh, ids.astype(np.int32))
    meshes = {spec.objects[k].mesh: t.mesh for k, t in enumerate(kept)}
    return ImportedScene(spec, meshes, with_ids, report, agreement.picture, tuple(warnings))


def write_imported(imported: ImportedScene, out: Path) -> None:
    """Write the scene into the (staged, empty) directory `out`."""
    for rel, mesh in imported.meshes.items():
        write_bytes(out / rel, mesh.export(file_type="ply"))
    write_bytes(out / SCENE_FILE, dumps_json(imported.spec.model_dump(mode="json", exclude_defaults=True)).encode())
    write_ply(out / TRAINED_FILES[0], imported.gaussians)  # a scene directory's trained Gaussians
    write_bytes(out / REPORT_FILE, dumps_json(imported.report).encode())
    write_bytes(out / OCCUPANCY_PICTURE, imported.picture)


# ---------------------------------------------------------------- structure


@dataclass(frozen=True)
class _StructureIndex:
    """What Gaussians near structure are matched against: wall pieces (boxes), room floors and ceilings."""

    wall_boxes: list[OrientedBox]
    wall_ids: np.ndarray  # [pieces] instance id of each piece's wall
    rooms: list[shapely.Polygon]
    slabs: list[_Thing]  # floor and ceiling of room 0, of room 1, ...

    def ids(self, points: np.ndarray, margin: float, *, across_only: bool = False) -> np.ndarray:
        """[N] the wall, floor or ceiling within `margin` of each point, 0 for none (walls first). `across_only`
        grows the wall pieces only across the wall, so a window or door in an opening keeps its edges."""
        out = np.zeros(len(points), dtype=np.int64)
        grow = np.array([0.0 if across_only else margin, margin, 0.0 if across_only else margin])
        owner = box_owner(points, [OrientedBox(b.centre, b.axes, b.half + grow) for b in self.wall_boxes])
        out[owner >= 0] = self.wall_ids[owner[owner >= 0]]
        z = points[:, 2]
        for k, poly in enumerate(self.rooms):
            floor, ceiling = self.slabs[2 * k], self.slabs[2 * k + 1]
            grown = poly.buffer(margin)
            for slab_id, height in ((floor.instance_id, 0.0), (ceiling.instance_id, ceiling.mesh.bounds[0][2])):
                near = np.flatnonzero((out == 0) & (np.abs(z - height) <= margin))  # only these need the polygon
                out[near[shapely.contains_xy(grown, points[near, 0], points[near, 1])]] = slab_id
        return out


def _rooms(folder: InteriorGSFolder) -> list[shapely.Polygon]:
    out = []
    for k, room in enumerate(folder.rooms):
        poly = room_polygon(room)
        if not poly.is_valid or poly.area <= 0:
            raise DataError(f"the outline is not a simple polygon of some area ({shapely.is_valid_reason(poly)})",
                            path=folder.path / STRUCTURE, field=f"rooms[{k}].profile")
        out.append(poly)
    return out


def _walls(folder: InteriorGSFolder) -> tuple[list[_Thing], list[OrientedBox], list[int], set[int]]:
    """One object per wall (its openings cut), its pieces as boxes with the wall each belongs to (index), and the
    openings that found a wall."""
    walls: list[_Thing] = []
    pieces: list[OrientedBox] = []
    piece_wall: list[int] = []
    taken: set[int] = set()
    for wall in folder.walls:
        openings = openings_on(wall, folder.holes, taken)
        taken |= {o.hole for o in openings}
        boxes = wall_pieces(wall, openings)
        walls.append(_Thing(0, "wall", "wall", mesh=trimesh.util.concatenate([box_mesh(b) for b in boxes]),
                            segment=wall, openings=openings))
        pieces += boxes
        piece_wall += [len(walls) - 1] * len(boxes)
    return walls, pieces, piece_wall, taken


def _slabs(folder: InteriorGSFolder, rooms: list[shapely.Polygon]) -> list[_Thing]:
    """A floor slab under and a ceiling slab over each room (at the height of the walls around it)."""
    out = []
    heights = [w.height for w in folder.walls]
    for k, poly in enumerate(rooms):
        near = [w.height for w in folder.walls
                if shapely.LineString([w.a, w.b]).distance(poly.exterior) <= w.thickness]
        top = max(near or heights or [DEFAULT_CEILING_M])
        out.append(_Thing(0, "floor", "floor", mesh=slab(poly, -SLAB_M, 0.0), room_id=f"room_{k}"))
        out.append(_Thing(0, "ceiling", "ceiling", mesh=slab(poly, top, top + SLAB_M), room_id=f"room_{k}"))
    return out


def _labelled(folder: InteriorGSFolder, rooms: list[shapely.Polygon]) -> list[_Thing]:
    """The labelled objects in file order, structural classes aside (walls, floors, ceilings come from the plan)."""
    objects = []
    for lab in folder.labels:
        try:
            box = box_from_corners(lab.corners)
        except BoxError as err:
            raise DataError(str(err), path=folder.path / LABELS, field=f"[{lab.index}].bounding_box") from None
        category = snake(lab.label) or "object"
        if category in STRUCTURAL_LABELS:
            continue
        kind = "window" if category == "window" else "object"
        objects.append(_Thing(0, category, kind, room_id=_room_of(box.centre, rooms), label=lab.index, box=box))
    return objects


def _match_doors(objects: list[_Thing], walls: list[_Thing], folder: InteriorGSFolder,
                 rooms: list[shapely.Polygon]) -> None:
    """Each DOOR opening takes the nearest unclaimed door label within its width: that label becomes a door, its
    state, hinge and swing read off its box."""
    doors = [t for t in objects if t.category == "door"]
    for wall in walls:
        seg = wall.segment
        u = (seg.b - seg.a) / max(float(np.linalg.norm(seg.b - seg.a)), 1e-12)
        for opening in wall.openings:
            if folder.holes[opening.hole].kind != "DOOR":
                continue
            centre = seg.a + u * (opening.s0 + opening.s1) / 2
            reach = opening.s1 - opening.s0 + DOOR_REACH_M
            near = [(float(np.linalg.norm(t.box.centre[:2] - centre)), t.label, t) for t in doors if t.door is None]
            near = [n for n in near if n[0] <= reach]
            if not near:
                continue
            door = min(near, key=lambda n: n[:2])[2]
            pose = door_pose(door.box, seg, opening)
            degrees = {"open": {"open_deg": pose.angle_deg}, "ajar": {"ajar_deg": pose.angle_deg}}.get(pose.state, {})
            door.kind, door.pose = "door", pose
            door.door = Door(state=pose.state, hinge=pose.hinge, swing=pose.swing, **degrees)


def _renamed_ids(folder: InteriorGSFolder) -> list[str]:
    renamed = [lab for lab in folder.labels if lab.renamed_from is not None]
    if not renamed:
        return []
    return [f"{len(renamed)} labels repeat an earlier label's ins_id and are renamed, so that each ins_id names one "
            "instance: labels.json " + ", ".join(f"[{lab.index}] {lab.renamed_from!r} -> {lab.ins_id!r}"
                                                 for lab in renamed[:10]) + (" ..." if len(renamed) > 10 else "")]


def _openings_on_no_wall(folder: InteriorGSFolder, matched: set[int]) -> list[str]:
    """A warning for the holes no wall took (their doors and windows are left out), naming 0 m walls if any."""
    lost = sorted(set(range(len(folder.holes))) - matched)
    if not lost:
        return []
    points = [k for k, w in enumerate(folder.walls) if np.allclose(w.a, w.b)]
    why = f" (walls of length 0: {', '.join(f'walls[{k}]' for k in points[:10])})" if points else ""
    return [f"{len(lost)} openings lie on no wall, so no wall is cut for them{why}: structure.json "
            + ", ".join(f"holes[{k}] ({folder.holes[k].kind})" for k in lost[:10]) + (" ..." if len(lost) > 10 else "")]


def _check_voxel_budget(folder: InteriorGSFolder, objects: list[_Thing], voxel: float) -> None:
    """Refuse, before anything is allocated, an object whose surface grid would exceed MAX_VOXELS: the label's box
    when it is too big even at the default voxel, else --voxel."""
    if not objects:
        return
    worst = max(objects, key=lambda t: grid_voxels(t.box.half, voxel))
    cells = grid_voxels(worst.box.half, voxel)
    if cells <= MAX_VOXELS:
        return
    size = " x ".join(f"{2 * h:.2f}".rstrip("0").rstrip(".") for h in worst.box.half)
    default = InteriorGSConfig.model_fields["voxel"].default
    if voxel >= default or grid_voxels(worst.box.half, default) > MAX_VOXELS:
        raise DataError(f"a box of {size} m is {cells:.2g} voxels at --voxel {voxel:g} m, over the budget of "
                        f"{MAX_VOXELS:.2g} voxels per object", path=folder.path / LABELS,
                        field=f"[{worst.label}].bounding_box")
    raise ConfigError(f"{voxel:g} m makes {cells:.2g} voxels of the {size} m box of labels.json [{worst.label}] "
                      f"({worst.category}), over the budget of {MAX_VOXELS:.2g} voxels per object; use --voxel "
                      f"{_coarsest_fit(worst.box.half):g} or more", field="--voxel")


def _coarsest_fit(half: np.ndarray) -> float:
    """The finest voxel (m, rounded up to a tenth of a millimetre) whose grid over the box fits MAX_VOXELS."""
    lo, hi = 1e-6, 1.0
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (lo, mid) if grid_voxels(half, mid) <= MAX_VOXELS else (mid, hi)
    return math.ceil(hi * 1e4) / 1e4


def _room_of(point: np.ndarray, rooms: list[shapely.Polygon]) -> str | None:
    for k, poly in enumerate(rooms):
        if shapely.contains_xy(poly, float(point[0]), float(point[1])):
            return f"room_{k}"
    return None


# ---------------------------------------------------------------- Gaussians


def _assign(means: np.ndarray, stray: np.ndarray, objects: list[_Thing], structure: _StructureIndex,
            config: InteriorGSConfig) -> tuple[np.ndarray, dict[str, float]]:
    """[N] instance id per Gaussian (module docstring), -1 for the floaters (`stray` [N]), and the shares of the
    three outcomes among the rest."""
    pts = means.astype(np.float64)
    ids = structure.ids(pts, config.structure_margin, across_only=True)
    ids[stray] = -1
    free = np.flatnonzero(ids == 0)
    owner = box_owner(pts[free], [t.box for t in objects], config.box_margin)
    _on_tops(pts[free], owner, objects, config.box_margin)
    in_box = owner >= 0
    if objects:
        ids[free[in_box]] = np.array([t.instance_id for t in objects], dtype=np.int64)[owner[in_box]]
    rest = np.flatnonzero(ids == 0)
    ids[rest] = structure.ids(pts[rest], config.structure_reach)
    n = max(len(pts) - int(stray.sum()), 1)
    objects_share = float(in_box.sum()) / n
    background = float((ids == 0).sum()) / n
    return ids, {"object_boxes": round(objects_share, 4), "structure": round(1 - objects_share - background, 4),
                 "background": round(background, 4)}


def _on_tops(pts: np.ndarray, owner: np.ndarray, objects: list[_Thing], margin: float) -> None:
    """Gaussians on the bottom face of their box that lie on the top face of a box under it go to that one: a TV's
    box starts where its stand's top is, and the Gaussians of that top are the stand's (`owner` is updated)."""
    for k, t in enumerate(objects):
        mine = np.flatnonzero(owner == k)
        bottom = t.box.centre[2] - t.box.half[2]
        low = mine[(pts[mine] - t.box.centre) @ t.box.axes[2] <= -t.box.half[2] + margin]
        under = [j for j, o in enumerate(objects) if j != k and abs(o.box.centre[2] + o.box.half[2] - bottom) <= margin]
        if len(low) and under:
            got = box_owner(pts[low], [objects[j].box for j in under], margin)
            owner[low[got >= 0]] = np.array(under)[got[got >= 0]]


def _surfaces(g: Gaussians, ids: np.ndarray, objects: list[_Thing], settings: SurfaceSettings) -> list[int]:
    """Give each object its surface from its own Gaussians; returns the labels.json indices left without one."""
    sel = np.flatnonzero(np.isin(ids, [t.instance_id for t in objects]))
    chosen = g.take(sel)
    points, weights, source = gaussian_points(chosen, settings.voxel)
    cov = gaussian_covariances(chosen)  # per Gaussian: a point takes its own Gaussian's (no copy for every point)
    owner = ids[sel][source]
    order = np.argsort(owner, kind="stable")
    bounds = np.searchsorted(owner[order], [[t.instance_id, t.instance_id + 1] for t in objects]) if objects else []
    empty = []
    for t, (a, b) in ui.track(list(zip(objects, bounds)), "object surfaces"):
        rows = order[a:b]
        mesh = object_surface(points[rows], weights[rows], t.box.centre, t.box.axes, t.box.half, settings,
                              cov[source[rows]]) if len(rows) else None
        if mesh is None:
            empty.append(t.label)
            continue
        if t.pose is not None:
            t.posed = mesh
            mesh = mesh.copy()
            mesh.apply_transform(t.pose.closing())
        t.mesh = mesh
    return empty


@dataclass(frozen=True)
class _Evidence:
    things: list[_Thing]
    found: Unlabelled


def _unlabelled(folder: InteriorGSFolder, rooms: list[shapely.Polygon], g: Gaussians, ids: np.ndarray,
                blocked: np.ndarray, band: tuple[float, float], config: InteriorGSConfig, first_id: int) -> _Evidence:
    """The obstacles no label explains (importers/interiorgs_evidence.py), as things numbered from `first_id`; the
    background Gaussians over each, up to its top, become its own (`ids` is updated)."""
    background = np.flatnonzero(ids == 0)
    means = g.means[background].astype(np.float64)
    alpha = 1.0 / (1.0 + np.exp(-g.opacity_logits[background].astype(np.float64)))
    found = unlabelled_obstacles(folder.occupancy, blocked, rooms, means, alpha, band, config.min_opacity,
                                 config.unlabelled_min_area)
    things = [_Thing(first_id + k, UNLABELLED, "object", mesh=mesh,
                     room_id=_room_of(mesh.bounds.mean(axis=0), rooms)) for k, mesh in enumerate(found.meshes)]
    res = folder.occupancy.scale
    j = np.clip(np.floor((means[:, 0] - folder.occupancy.origin[0]) / res).astype(np.int64), 0, found.cells.shape[1] - 1)
    i = np.clip(np.floor((means[:, 1] - folder.occupancy.origin[1]) / res).astype(np.int64), 0, found.cells.shape[0] - 1)
    over = found.cells[i, j]
    tops = np.array([0.0, *found.tops])
    mine = (over > 0) & (means[:, 2] <= tops[over] + config.box_margin)
    ids[background[mine]] = first_id + over[mine] - 1
    return _Evidence(things, found)


def _use_collision_meshes(path: Path, objects: list[_Thing]) -> dict:
    """Replace the surfaces of the objects that SAGE-3D's collision USD has meshes for; what matched, for the report."""
    from sagebench.importers.collision_usd import match_collision_meshes

    match = match_collision_meshes(path, [t.box for t in objects])
    for k, mesh in match.meshes.items():
        t = objects[k]
        if t.pose is not None:
            t.posed = mesh
            mesh = mesh.copy()
            mesh.apply_transform(t.pose.closing())
        t.mesh = mesh
    return {"file": path.name, "prims": match.prims, "pieces": match.pieces, "matched_pieces": match.matched_pieces,
            "objects": len(match.meshes), "turned_180_about_z": match.turned}


# ---------------------------------------------------------------- scene.json


def _spec(scene_id: str, folder: InteriorGSFolder, rooms: list[shapely.Polygon], things: list[_Thing],
          offset: tuple[float, float]) -> SceneSpec:
    room_models = [Room(id=f"room_{k}", type=room_type(r.room_type),
                        polygon=[(float(x), float(y)) for x, y in np.asarray(poly.exterior.coords)[:-1]])
                   for k, (r, poly) in enumerate(zip(folder.rooms, rooms))]
    objects = [SceneObject(instance_id=t.instance_id, category=t.category, kind=t.kind,
                           mesh=f"meshes/{t.instance_id:05d}-{t.category}.ply", room_id=t.room_id, door=t.door)
               for t in things]
    try:
        return SceneSpec(scene_id=scene_id, rooms=room_models, objects=objects, sage_offset=offset)
    except ValidationError as err:
        loc, msg, _ = first_error(err)
        if loc == "scene_id":
            raise DataError(f"the folder name {scene_id!r} is not a usable scene id (letters, digits, '_', '.', '-'; "
                            "rename the folder)", path=folder.path) from None
        raise DataError(msg, path=folder.path, field=loc) from None
