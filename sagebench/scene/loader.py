"""Read an artist scene directory into world-space meshes (metres, Z up) keyed by instance id."""

from __future__ import annotations

import hashlib
import json
import math
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING
from urllib.parse import unquote

import numpy as np
from pydantic import ValidationError

from sagebench.errors import MeshError, SceneError, first_error
from sagebench.run_layout import SCENE_FILE  # an artist's scene directory and a run's scenes/<id>/ alike
from sagebench.fileio import hash_file
from sagebench.input_files import loads_json
from sagebench.scene.mesh_budget import MAX_MESH_FACES, budget_problem, faces_problem
from sagebench.scene.checks import check_hinge, check_inside_rooms, check_rooms, check_world_bounds
from sagebench.scene.model import UNIT_SCALE, Door, Room, SceneObject, SceneSpec, Transform

if TYPE_CHECKING:  # trimesh costs a third of a second to import: only what reads meshes pays it
    import trimesh


@dataclass(frozen=True)
class LoadedScene:
    """A scene ready for every later stage.

    `spec` is normalised: units m, up_axis Z, floor polygons as [x, y], transforms as the 4x4 matrix that
    takes the mesh file's coordinates to world metres. `meshes` are in world space with doors posed at
    their state's angle. `source_sha256` hashes scene.json and every mesh file it names.
    """

    spec: SceneSpec
    meshes: dict[int, trimesh.Trimesh]
    source_dir: Path
    source_sha256: str

    def object(self, instance_id: int) -> SceneObject:
        return next(o for o in self.spec.objects if o.instance_id == instance_id)


def frame_matrix(units: str, up_axis: str) -> np.ndarray:
    """[4, 4] matrix from the scene's input frame and units to metres, Z up (Y up turns +90 deg about X)."""
    s = UNIT_SCALE[units]
    axes = np.eye(3) if up_axis == "Z" else np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
    out = np.eye(4)
    out[:3, :3] = axes * s
    return out


def parse_spec(text: str | bytes, where: Path | str) -> SceneSpec:
    """Validate scene.json text (or its UTF-8 bytes); every failure is one SceneError naming the field."""
    raw = loads_json(text, where, SceneError)
    try:
        return SceneSpec.model_validate(raw)
    except ValidationError as err:
        raise SceneError(_first_error(err), path=where) from None


def _first_error(err: ValidationError) -> str:
    loc, msg, e = first_error(err)
    if e["type"] in ("literal_error", "string_pattern_mismatch", "greater_than_equal", "missing") or "input" in e:
        got = e.get("input")
        if e["type"] != "missing" and not isinstance(got, dict | list):
            msg = f"{msg} (got {got!r})"
    return f"{loc}: {msg}" if loc else msg


def load_scene(scene_dir: Path | str) -> LoadedScene:
    """Load and normalise a scene directory; raises SceneError/MeshError with one clear line."""
    scene_dir = Path(scene_dir)
    spec_path = scene_dir / SCENE_FILE
    if not spec_path.is_file():
        raise SceneError(f"no {SCENE_FILE} in this directory", path=scene_dir)
    try:
        text = spec_path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise SceneError(f"cannot read: {err}", path=spec_path) from None
    spec = parse_spec(text, spec_path)
    hasher = hashlib.sha256(text.encode())
    frame = frame_matrix(spec.units, spec.up_axis)
    cache: dict[Path, trimesh.Trimesh] = {}
    meshes: dict[int, trimesh.Trimesh] = {}
    objects = []
    for i, obj in enumerate(spec.objects):
        field = f"objects[{i}].mesh"
        mesh_path = resolve_mesh_path(scene_dir, obj.mesh, spec_path, field)
        if mesh_path not in cache:
            check_budget(mesh_path, spec_path, field)
            for name in mesh_files(scene_dir, obj.mesh, spec_path, field):  # a .gltf's buffers checked first
                hasher.update(name.encode() + b"\0")
                _hash_file(scene_dir / name, hasher, spec_path, field)
            cache[mesh_path] = read_mesh(mesh_path, spec_path, field)
        to_world = frame @ obj.transform.as_matrix()
        world = cache[mesh_path].copy()
        with np.errstate(over="ignore", invalid="ignore"):  # an overflow to inf is refused with one line below
            world.apply_transform(to_world)
        door = _normalise_door(obj.door, frame) if obj.door else None
        if door is not None:
            check_hinge(door, world.bounds, spec_path, f"objects[{i}].door.hinge")
            world.apply_transform(door_pose(door))
        meshes[obj.instance_id] = world
        objects.append(
            obj.model_copy(update={"transform": Transform(matrix=_rows(to_world)), "door": door})
        )
    normalised = spec.model_copy(
        update={
            "units": "m",
            "up_axis": "Z",
            "floor_height": float((frame @ _up_point(spec))[2]),
            "rooms": [_normalise_room(r, frame) for r in spec.rooms],
            "objects": objects,
        }
    )
    bounds = {k: np.asarray(m.bounds) for k, m in meshes.items()}
    check_world_bounds(bounds, normalised, spec.units, spec_path)
    check_rooms(normalised.rooms, spec_path)
    check_inside_rooms(normalised, bounds, spec_path)
    return LoadedScene(spec=normalised, meshes=meshes, source_dir=scene_dir, source_sha256=hasher.hexdigest())


def write_normalised_scene(scene: LoadedScene, dest: Path) -> None:
    """Write the normalised scene.json and a copy of every mesh it names into `dest`.

    `dest` is then a scene directory of its own: load_scene(dest) gives the same world meshes, so every
    later stage reads `scenes/<scene_id>/` of a run and never the artist's directory.
    """
    from sagebench.fileio import copy_file, dumps_json, write_bytes

    names = {n for o in scene.spec.objects for n in mesh_files(scene.source_dir, o.mesh, scene.source_dir / SCENE_FILE,
                                                               "objects.mesh")}
    for name in sorted(names):
        copy_file(scene.source_dir / name, dest / name)
    write_bytes(dest / SCENE_FILE, dumps_json(scene.spec.model_dump(mode="json", exclude_defaults=True)).encode())


def resolve_mesh_path(scene_dir: Path, mesh: str, spec_path: Path, field: str) -> Path:
    rel = Path(mesh)
    if rel.is_absolute() or ".." in rel.parts:
        raise MeshError(f"mesh path {mesh!r} leaves the scene directory", path=spec_path, field=field)
    path = scene_dir / rel
    if not path.resolve().is_relative_to(scene_dir.resolve()):
        raise MeshError(f"mesh path {mesh!r} is a link that leaves the scene directory", path=spec_path, field=field)
    try:
        is_file = stat.S_ISREG(path.stat().st_mode)
    except (FileNotFoundError, NotADirectoryError):
        is_file = False
    except OSError as err:  # a directory on the way that may not be searched
        raise MeshError(f"cannot read mesh file {mesh!r}: {err.strerror or err}", path=spec_path, field=field) from None
    if not is_file:
        raise MeshError(f"mesh file {mesh!r} does not exist", path=spec_path, field=field)
    return path


def check_budget(path: Path, spec_path: Path, field: str) -> None:
    """A MeshError when the mesh file is over the size or face budget (mesh_budget.py), told by its size and
    header before it is read."""
    problem = budget_problem(path)
    if problem is not None:
        raise MeshError(f"mesh {path.name!r} {problem}", path=spec_path, field=field)


def _hash_file(path: Path, hasher, spec_path: Path, field: str) -> None:
    try:
        hash_file(path, hasher)
    except OSError as err:
        raise MeshError(f"cannot read mesh file {path.name!r}: {err.strerror or err}", path=spec_path, field=field) from None


def mesh_files(scene_dir: Path, mesh: str, spec_path: Path, field: str) -> list[str]:
    """The files a mesh is made of, relative to the scene directory: the mesh itself and, for a .gltf, the
    buffers and images it names by relative URI (copied and hashed with it; one leaving the scene is refused)."""
    files = [mesh]
    if Path(mesh).suffix.lower() != ".gltf":
        return files
    try:
        doc = json.loads((scene_dir / mesh).read_text(encoding="utf-8"))
        uris = [e["uri"] for key in ("buffers", "images") for e in doc.get(key, []) if "uri" in e]
    except (OSError, UnicodeDecodeError, ValueError, RecursionError, TypeError, AttributeError, KeyError):
        raise MeshError(f"cannot read glTF {mesh!r} as JSON with buffers and images", path=spec_path, field=field) from None
    for uri in uris:
        if not isinstance(uri, str):
            raise MeshError(f"glTF {mesh!r} has a non-string URI", path=spec_path, field=field)
        if uri.startswith("data:"):
            continue
        name = (Path(mesh).parent / unquote(uri)).as_posix()
        resolve_mesh_path(scene_dir, name, spec_path, field)
        files.append(name)
    return files


def read_mesh(path: Path, spec_path: Path, field: str) -> trimesh.Trimesh:
    """One triangle mesh from a GLB/GLTF/OBJ/PLY file, in the file's own coordinates."""
    import trimesh

    check_budget(path, spec_path, field)
    try:
        mesh = trimesh.load(path, force="mesh", process=False)
    except OSError as err:
        raise MeshError(f"cannot read mesh {path.name!r}: {err.strerror or err}", path=spec_path, field=field) from None
    except Exception as err:  # trimesh raises many types for a bad file
        raise MeshError(f"cannot read mesh {path.name!r}: {err}", path=spec_path, field=field) from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0 or len(mesh.vertices) == 0:
        raise MeshError(f"mesh {path.name!r} has no triangles", path=spec_path, field=field)
    if len(mesh.faces) > MAX_MESH_FACES:
        raise MeshError(f"mesh {path.name!r} {faces_problem(len(mesh.faces))}", path=spec_path, field=field)
    if not np.isfinite(mesh.vertices).all():
        raise MeshError(f"mesh {path.name!r} has non-finite vertex coordinates", path=spec_path, field=field)
    if not np.ptp(mesh.vertices, axis=0).any():
        raise MeshError(f"mesh {path.name!r} has all its vertices at one point", path=spec_path, field=field)
    return mesh


def door_pose(door: Door) -> np.ndarray:
    """[4, 4] rotation of a world-space (Z up) closed leaf about its hinge to its state's angle."""
    import trimesh

    return trimesh.transformations.rotation_matrix(door.angle_rad(), [0, 0, 1], point=door.hinge)


def _normalise_door(door: Door, frame: np.ndarray) -> Door:
    hinge = (frame @ np.array([*door.hinge, 1.0]))[:3]
    return door.model_copy(update={"hinge": tuple(float(v) for v in hinge)})


def _normalise_room(room: Room, frame: np.ndarray) -> Room:
    pts = np.array(room.polygon, dtype=np.float64)
    if pts.shape[1] == 2:
        pts = np.column_stack([pts, np.zeros(len(pts))])
    world = (frame[:3, :3] @ pts.T).T
    return room.model_copy(update={"polygon": [(float(x), float(y)) for x, y in world[:, :2]]})


def _up_point(spec: SceneSpec) -> np.ndarray:
    up = np.zeros(4)
    up[3] = 1.0
    up[2 if spec.up_axis == "Z" else 1] = spec.floor_height
    return up


def _rows(m: np.ndarray) -> tuple[tuple[float, ...], ...]:
    return tuple(tuple(float(v) for v in row) for row in m)


def yaw_quaternion(yaw: float) -> tuple[float, float, float, float]:
    """wxyz quaternion of a rotation by `yaw` radians about +Z."""
    return (math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2))
