"""Damaged inputs: each is refused with exit status 2, one line naming the file and the field, nothing written.

The cases are tables of mutations applied to one tiny valid scene (5 objects, one room) and to one run built
from it: every number of scene.json replaced by a string, null, NaN or a boolean, every mesh broken six ways,
every property of a trained gaussians.ply made NaN or removed, damaged run outputs, predictions and run.toml
files. `test_at_least_250_distinct_damaged_inputs` counts the distinct inputs.
"""

from __future__ import annotations

import copy
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from profiles import examples

from sagebench.errors import field_path

# ---------------------------------------------------------------- the tiny valid scene


def _box_bytes(extents: tuple[float, float, float], ext: str) -> bytes:
    data = trimesh.creation.box(extents=extents).export(file_type=ext)
    return data.encode() if isinstance(data, str) else bytes(data)


MESHES = {  # mesh file -> (box extents m, index of the object using it)
    "meshes/floor.ply": ((6, 4, 0.1), 0),
    "meshes/wall.obj": ((6, 0.1, 2.5), 1),
    "meshes/table.glb": ((1.0, 0.6, 0.75), 2),
    "meshes/door.glb": ((0.9, 0.04, 2.0), 3),
    "meshes/cabinet.ply": ((0.5, 0.5, 1.8), 4),
}

SPEC: dict[str, Any] = {
    "scene_id": "tiny", "units": "m", "up_axis": "Z", "floor_height": 0.0,
    "rooms": [{"id": "r0", "type": "kitchen", "polygon": [[0.0, 0.0], [6.0, 0.0], [6.0, 4.0], [0.0, 4.0]]}],
    "objects": [
        {"instance_id": 1, "category": "floor", "kind": "floor", "mesh": "meshes/floor.ply",
         "transform": {"translation": [3.0, 2.0, -0.05]}, "room_id": "r0"},
        {"instance_id": 2, "category": "wall", "kind": "wall", "mesh": "meshes/wall.obj",
         "transform": {"translation": [3.0, 4.05, 1.25]}},
        {"instance_id": 3, "category": "table", "mesh": "meshes/table.glb",
         "transform": {"translation": [1.0, 1.0, 0.375], "rotation_wxyz": [1.0, 0.0, 0.0, 0.0],
                       "scale": [1.0, 1.0, 1.0]}, "attributes": {"colour": "red"}, "room_id": "r0"},
        {"instance_id": 4, "category": "door", "kind": "door", "mesh": "meshes/door.glb",
         "transform": {"matrix": [[1.0, 0.0, 0.0, 4.45], [0.0, 1.0, 0.0, 4.0], [0.0, 0.0, 1.0, 1.0],
                                  [0.0, 0.0, 0.0, 1.0]]},
         "door": {"state": "closed", "hinge": [4.0, 4.0, 0.0], "swing": 1, "open_deg": 90.0, "ajar_deg": 45.0}},
        {"instance_id": 5, "category": "cabinet", "mesh": "meshes/cabinet.ply",
         "transform": {"translation": [5.0, 3.0, 0.9]}, "attributes": {"colour": "blue"}},
    ],
}


def write_scene(d: Path, spec: dict[str, Any] | str = SPEC) -> Path:
    for name, (extents, _) in MESHES.items():
        (d / name).parent.mkdir(parents=True, exist_ok=True)
        (d / name).write_bytes(_box_bytes(extents, name.rsplit(".", 1)[1]))
    (d / "scene.json").write_text(spec if isinstance(spec, str) else json.dumps(spec, indent=1))
    return d


def snapshot(root: Path) -> dict[str, tuple[int, bytes]]:
    """Every file under root -> (size, digest): equal before and after means nothing was written or removed."""
    return {str(p.relative_to(root)): (p.stat().st_size, _digest(p))
            for p in sorted(root.rglob("*")) if p.is_file() and not p.is_symlink()}


def _digest(path: Path) -> bytes:
    """sha256 of the file's data and where each run of it lies: the holes of a sparse file (zeros, unless written
    into, which makes them data) are not read, so the 2 GiB sparse mesh of test_fuzz_safety costs nothing."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        pos, end = 0, os.fstat(f.fileno()).st_size
        while pos < end:
            try:
                start = os.lseek(f.fileno(), pos, os.SEEK_DATA)
            except OSError:  # ENXIO: a hole up to the end
                break
            pos = os.lseek(f.fileno(), start, os.SEEK_HOLE)
            h.update(b"%d-%d:" % (start, pos))
            f.seek(start)
            h.update(f.read(pos - start))
    return h.digest()


def assert_refused(run_cli, args: list, where: Path, expect: str) -> None:
    """Exit 2, exactly one stderr line `error: ...` containing `expect`, no stdout, `where` unchanged."""
    before = snapshot(where)
    code, out, err = run_cli(*args)
    lines = err.splitlines()
    assert (code, out, len(lines)) == (2, "", 1), (code, out, err)
    assert lines[0].startswith("error: ") and expect in lines[0], (expect, lines[0])
    assert "Traceback" not in err
    assert snapshot(where) == before


def assert_scene_refused(run_cli, scene: Path, where: Path, expect: str, check_expect: str | None = None) -> None:
    """check-scene refuses what build-scene refuses (their parity); check_expect where its line differs."""
    assert_refused(run_cli, ["check-scene", scene], where, expect if check_expect is None else check_expect)
    assert_refused(run_cli, ["build-scene", scene, "--out", where / "run"], where, expect)


# ---------------------------------------------------------------- scene.json: every leaf, four ways


def _leaves(node: Any, loc: tuple = ()) -> list[tuple[tuple, Any]]:
    if isinstance(node, dict):
        return [leaf for k, v in node.items() for leaf in _leaves(v, (*loc, k))]
    if isinstance(node, list):
        return [leaf for i, v in enumerate(node) for leaf in _leaves(v, (*loc, i))]
    return [(loc, node)]


def _set(spec: dict, loc: tuple, value: Any) -> dict:
    out = copy.deepcopy(spec)
    node = out
    for key in loc[:-1]:
        node = node[key]
    node[loc[-1]] = value
    return out


BAD_NUMBERS = {"string": lambda v: str(v), "null": lambda v: None, "nan": lambda v: float("nan"),
               "bool": lambda v: True}
BAD_STRINGS = {"number": lambda v: 7, "null": lambda v: None, "list": lambda v: [v]}
OPTIONAL = {"room_id"}  # null is a valid value there


def leaf_cases() -> list[tuple[str, dict, str]]:
    """(case id, damaged spec, field the error names) for every leaf of SPEC."""
    cases = []
    for loc, value in _leaves(SPEC):
        if isinstance(value, bool):
            continue
        table = BAD_NUMBERS if isinstance(value, int | float) else BAD_STRINGS
        for how, bad in table.items():
            if how == "null" and loc[-1] in OPTIONAL:
                continue
            cases.append((f"{field_path(loc)}={how}", _set(SPEC, loc, bad(value)), field_path(loc)))
    return cases


def _obj(i: int, **changes: Any) -> dict:
    spec = copy.deepcopy(SPEC)
    spec["objects"][i].update(changes)
    return spec


def _top(**changes: Any) -> dict:
    return copy.deepcopy(SPEC) | changes


def _room(polygon: list) -> dict:
    spec = copy.deepcopy(SPEC)
    spec["rooms"][0]["polygon"] = polygon
    return spec


def _matrix(rows: list) -> dict:
    return _obj(3, transform={"matrix": rows})


DOOR = SPEC["objects"][3]["door"]

# (case id, damaged spec or raw text, what the error line contains after the file)
MEANING_CASES: list[tuple[str, dict | str, str]] = [
    ("scale-0", _obj(2, transform={"scale": [0.0, 1.0, 1.0]}), "objects[2].transform: singular transform"),
    ("scale-all-0", _obj(2, transform={"scale": [0.0, 0.0, 0.0]}), "objects[2].transform: singular transform"),
    ("scale-tiny", _obj(2, transform={"scale": [1e-5, 1e-5, 1e-5]}), "objects[2].transform: singular"),
    ("matrix-all-0", _matrix([[0.0] * 4] * 4), "objects[3].transform.matrix: matrix's last row must be 0 0 0 1"),
    ("matrix-flat", _matrix([[1.0, 0, 0, 4.45], [0, 1.0, 0, 4.0], [0, 0, 0.0, 1.0], [0, 0, 0, 1.0]]),
     "objects[3].transform: singular transform (determinant 0)"),
    ("matrix-rank1", _matrix([[1.0, 1, 1, 0], [1, 1, 1, 0], [1, 1, 1, 0], [0, 0, 0, 1]]), "singular transform"),
    ("matrix-last-row", _matrix([[1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]),
     "objects[3].transform.matrix: matrix's last row must be 0 0 0 1, got 0 0 1 1"),
    ("matrix-perspective", _matrix([[1.0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0.5, 0, 0, 1]]), "last row"),
    ("matrix-3x3", _matrix([[1.0, 0, 0], [0, 1, 0], [0, 0, 1]]), "matrix must be 4 rows of 4 numbers"),
    ("matrix-and-trs", _obj(3, transform={"matrix": SPEC["objects"][3]["transform"]["matrix"],
                                          "scale": [1.0, 1.0, 1.0]}), "give either matrix or scale"),
    ("quaternion-0", _obj(2, transform={"rotation_wxyz": [0.0, 0.0, 0.0, 0.0]}), "zero quaternion"),
    ("id-int32", _obj(0, instance_id=2**31), "objects[0].instance_id: Input should be less than or equal to 2147483647"),
    ("id-huge", _obj(4, instance_id=10**30), "objects[4].instance_id"),
    ("id-0", _obj(1, instance_id=0), "objects[1].instance_id: Input should be greater than or equal to 1"),
    ("id-negative", _obj(1, instance_id=-3), "objects[1].instance_id"),
    ("id-float", _obj(1, instance_id=2.5), "objects[1].instance_id"),
    ("id-duplicate", _obj(4, instance_id=3), "objects[4].instance_id: duplicate instance_id 3"),
    ("units-cm", _top(units="cm"), "units: the scene is 0.06 m x 0.041 m with units 'cm'"),
    ("units-mm", _top(units="mm"), "units: the scene is 0.006 m x 0.0041 m with units 'mm'"),
    ("units-km", _top(units="km"), "units: Input should be 'm', 'cm' or 'mm'"),
    ("units-huge-scale", _obj(4, transform={"translation": [5.0, 3.0, 0.9], "scale": [5000.0, 1.0, 1.0]}),
     "units: the scene is 2.5e+03 m"),
    ("far-away-1e300", _obj(4, transform={"translation": [1e300, 3.0, 0.9]}), "units: the scene is 1e+300 m"),
    ("overflow-inf", _obj(4, transform={"translation": [1.7e308, 3.0, 0.9], "scale": [1e308, 1.0, 1.0]}),
     "objects[4].transform: the transform takes the mesh to non-finite coordinates"),
    ("floor-1000-up", _top(floor_height=1000.0), "floor_height: the floor at 1e+03 m is more than 1 m outside"),
    ("floor-50-down", _top(floor_height=-50.0), "floor_height: the floor at -50 m"),
    ("floor-above-ceiling", _top(floor_height=3.6), "floor_height: the floor at 3.6 m"),
    ("hinge-far", _obj(3, door=DOOR | {"hinge": [0.5, 0.5, 0.0]}), "objects[3].door.hinge: the hinge is"),
    ("hinge-other-wall", _obj(3, door=DOOR | {"hinge": [4.0, 0.0, 0.0]}), "objects[3].door.hinge: the hinge is 3.98 m"),
    ("object-far-outside", _obj(4, transform={"translation": [60.0, 3.0, 0.9]}),
     "objects[4].transform: the object is 53.8 m outside every room"),
    ("object-below-rooms", _obj(4, transform={"translation": [5.0, -30.0, 0.9]}), "outside every room"),
    ("room-zero-area", _room([[0.0, 0.0], [6.0, 0.0], [3.0, 0.0]]), "rooms[0].polygon: the floor outline"),
    ("no-rooms-no-floor", _top(rooms=[], objects=[{k: v for k, v in o.items() if k != "room_id"}
                                                  for o in SPEC["objects"][1:]]),
     "scene.json: rooms: no rooms and no floor meshes: cannot tell where the floor is"),
    ("no-rooms-floor-edge-on", _top(rooms=[], objects=[
        {k: v for k, v in o.items() if k != "room_id"} | ({"transform": {  # a 6 m x 4 m x 0.1 mm plate on its side
            "translation": [3.0, 2.0, 0.0], "rotation_wxyz": [0.7071068, 0.7071068, 0.0, 0.0],
            "scale": [1.0, 1.0, 1e-3]}} if i == 0 else {})
        for i, o in enumerate(SPEC["objects"])]), "scene.json: rooms: no rooms and no floor meshes"),
    ("room-sliver", _room([[0.0, 0.0], [6.0, 0.0], [6.0, 0.001]]), "rooms[0].polygon: the floor outline encloses 0.003"),
    ("room-bowtie", _room([[0.0, 0.0], [6.0, 4.0], [6.0, 0.0], [0.0, 4.0]]),
     "rooms[0].polygon: the floor outline is not a simple polygon (Self-intersection"),
    ("room-one-point", _room([[1.0, 1.0]]), "rooms[0].polygon: a floor polygon needs at least 3 points"),
    ("room-two-points", _room([[1.0, 1.0], [2.0, 2.0]]), "rooms[0].polygon: a floor polygon needs at least 3 points"),
    ("room-mixed-dims", _room([[0.0, 0.0], [6.0, 0.0, 1.0], [6.0, 4.0]]), "polygon points must all be"),
    ("room-4d", _room([[0.0, 0.0, 0, 0], [6.0, 0.0, 0, 0], [6.0, 4.0, 0, 0]]), "polygon points must all be"),
    ("room-duplicate", _top(rooms=SPEC["rooms"] * 2), "rooms: duplicate room id"),
    ("room-unknown", _obj(0, room_id="attic"), "objects[0].room_id: unknown room 'attic'"),
    ("y-up-2d-polygon", _top(up_axis="Y"), "rooms[0].polygon: a Y-up scene needs [x, y, z] points"),
    ("scene-id-300", _top(scene_id="a" * 300), "scene_id: String should have at most 128 characters"),
    ("scene-id-slash", _top(scene_id="a/b"), "scene_id: String should match pattern"),
    ("scene-id-dots", _top(scene_id="../x"), "scene_id: String should match pattern"),
    ("scene-id-empty", _top(scene_id=""), "scene_id: String should match pattern"),
    ("mesh-nul", _obj(2, mesh="meshes/ta\u0000ble.glb"), "objects[2].mesh: String should match pattern"),
    ("mesh-dotdot", _obj(2, mesh="../table.glb"), "objects[2].mesh: mesh path '../table.glb' leaves the scene"),
    ("mesh-absolute", _obj(2, mesh="/etc/hostname"), "objects[2].mesh: mesh path '/etc/hostname' leaves the scene"),
    ("mesh-missing", _obj(2, mesh="meshes/nope.glb"), "objects[2].mesh: mesh file 'meshes/nope.glb' does not exist"),
    ("mesh-is-dir", _obj(2, mesh="meshes"), "objects[2].mesh: mesh file 'meshes' does not exist"),
    ("mesh-empty-name", _obj(2, mesh=""), "objects[2].mesh: String should have at least 1 character"),
    ("kind-unknown", _obj(2, kind="chair"), "objects[2].kind: Input should be"),
    ("door-without-entry", _obj(3, door=None), "objects[3]: a door needs a 'door' entry"),
    ("door-entry-on-table", _obj(2, door=DOOR), "objects[2]: only kind 'door' may have a 'door' entry"),
    ("door-state", _obj(3, door=DOOR | {"state": "half"}), "objects[3].door.state: Input should be"),
    ("door-swing-0", _obj(3, door=DOOR | {"swing": 0}), "objects[3].door.swing"),
    ("door-open-270", _obj(3, door=DOOR | {"open_deg": 270.0}), "objects[3].door.open_deg: Input should be less"),
    ("door-ajar-0", _obj(3, door=DOOR | {"ajar_deg": 0.0}), "objects[3].door.ajar_deg: Input should be greater"),
    ("unknown-field", _top(colour="red"), "colour: Extra inputs are not permitted"),
    ("unknown-object-field", _obj(2, weight=3.0), "objects[2].weight: Extra inputs are not permitted"),
    ("no-objects", _top(objects=[]), "objects: List should have at least 1 item"),
    ("objects-missing", {k: v for k, v in SPEC.items() if k != "objects"}, "objects: Field required"),
    ("scene-id-missing", {k: v for k, v in SPEC.items() if k != "scene_id"}, "scene_id: Field required"),
    ("objects-dict", _top(objects={"a": 1}), "objects: Input should be a valid list"),
    ("top-level-list", "[1, 2]", "Input should be a valid dictionary"),
    ("malformed", '{"scene_id": "tiny",', "malformed JSON at line 1, column 21"),
    ("trailing-garbage", json.dumps(SPEC) + " x", "malformed JSON at line 1"),
    ("nested-deeply", "[" * 100_000 + "]" * 100_000, "scene.json: JSON nested too deeply"),
    ("empty-file", "", "malformed JSON at line 1, column 1"),
]


def _as_text(spec: dict | str) -> str:
    return spec if isinstance(spec, str) else json.dumps(spec, indent=1)


SCENE_CASES = [(cid, _as_text(spec), f"scene.json: {field}: ") for cid, spec, field in leaf_cases()]
SCENE_CASES += [(cid, _as_text(spec), expect) for cid, spec, expect in MEANING_CASES]


def test_the_tiny_scene_is_valid(tiny_scene, run_cli, tmp_path):
    assert run_cli("check-scene", tiny_scene)[0] == 0


@pytest.mark.parametrize("text, expect", [c[1:] for c in SCENE_CASES], ids=[c[0] for c in SCENE_CASES])
def test_damaged_scene_json(text, expect, tiny_scene, run_cli, tmp_path):
    scene = tmp_path / "scene"
    shutil.copytree(tiny_scene, scene)
    (scene / "scene.json").write_text(text)
    assert_scene_refused(run_cli, scene, tmp_path, expect)


# ---------------------------------------------------------------- meshes: each file, six ways


def _one_point(ext: str) -> bytes:
    data = trimesh.Trimesh(vertices=[[1.0, 1.0, 1.0]] * 3, faces=[[0, 1, 2]], process=False).export(file_type=ext)
    return data.encode() if isinstance(data, str) else bytes(data)


def _outside_link(path: Path) -> None:
    outside = path.parents[2] / "outside.glb"
    outside.write_bytes(_box_bytes((1, 1, 1), "glb"))
    path.unlink()
    path.symlink_to(outside)


MESH_DAMAGE: dict[str, tuple[Callable[[Path], None], str]] = {
    "deleted": (lambda p: p.unlink(), "does not exist"),
    "empty": (lambda p: p.write_bytes(b""), "mesh"),
    "garbage": (lambda p: p.write_bytes(b"\x00\x01garbage" * 50), "mesh"),
    "directory": (lambda p: (p.unlink(), p.mkdir()), "does not exist"),
    "one-point": (lambda p: p.write_bytes(_one_point(p.suffix[1:])), "has all its vertices at one point"),
    "link-outside": (_outside_link, "is a link that leaves the scene directory"),
}
MESH_CASES = [(f"{name}-{how}", name, how) for name in MESHES for how in MESH_DAMAGE]


@pytest.mark.parametrize("name, how", [c[1:] for c in MESH_CASES], ids=[c[0] for c in MESH_CASES])
def test_damaged_mesh(name, how, tiny_scene, run_cli, tmp_path):
    scene = tmp_path / "scene"
    shutil.copytree(tiny_scene, scene)
    damage, expect = MESH_DAMAGE[how]
    damage(scene / name)
    field = f"scene.json: objects[{MESHES[name][1]}].mesh: "
    assert_scene_refused(run_cli, scene, tmp_path, expect, field)


GLTF_CASES = {
    "buffer-missing": ({"uri": "table.bin"}, False, "mesh file 'meshes/table.bin' does not exist"),
    "buffer-leaves": ({"uri": "../../table.bin"}, True, "mesh path 'meshes/../../table.bin' leaves the scene"),
    "buffer-absolute": ({"uri": "/tmp/table.bin"}, True, "mesh path '/tmp/table.bin' leaves the scene directory"),
}


@pytest.mark.parametrize("case", list(GLTF_CASES))
def test_gltf_buffers_must_stay_in_the_scene(case, tiny_scene, run_cli, tmp_path):
    buffer, write_it, expect = GLTF_CASES[case]
    scene = tmp_path / "scene"
    shutil.copytree(tiny_scene, scene)
    files = trimesh.creation.box(extents=(1.0, 0.6, 0.75)).export(file_type="gltf")
    doc = json.loads(files["model.gltf"])
    data = next(v for k, v in files.items() if k.endswith(".bin"))
    doc["buffers"] = [{"byteLength": len(data), **buffer}]
    (scene / "meshes" / "table.gltf").write_text(json.dumps(doc))
    if write_it:
        (scene / "meshes" / "table.bin").write_bytes(data)
    (scene / "scene.json").write_text(json.dumps(_obj(2, mesh="meshes/table.gltf")))
    assert_scene_refused(run_cli, scene, tmp_path, expect, f"scene.json: objects[2].mesh: {expect}")


def test_gltf_buffers_are_copied_into_the_run(tiny_scene, run_cli, tmp_path):
    """A .gltf whose buffer is a separate file builds, and the run's copy of the scene loads on its own."""
    from sagebench.scene.loader import load_scene

    scene = tmp_path / "scene"
    shutil.copytree(tiny_scene, scene)
    for name, data in trimesh.creation.box(extents=(1.0, 0.6, 0.75)).export(file_type="gltf").items():
        (scene / "meshes" / ("table.gltf" if name.endswith(".gltf") else name)).write_bytes(data)
    (scene / "scene.json").write_text(json.dumps(_obj(2, mesh="meshes/table.gltf")))
    built = load_scene(scene)
    from sagebench.scene.loader import write_normalised_scene

    write_normalised_scene(built, tmp_path / "copy")
    copy_ = load_scene(tmp_path / "copy")
    np.testing.assert_array_equal(copy_.meshes[3].vertices, built.meshes[3].vertices)


# ---------------------------------------------------------------- a trained gaussians.ply: NaN, missing, malformed

BASE_PROPS = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2",
              "rot_0", "rot_1", "rot_2", "rot_3"]


def _ply_table() -> np.ndarray:
    rng = np.random.default_rng(0)
    n = 16
    table = np.zeros(n, dtype=[(p, "<f4") for p in BASE_PROPS])
    for axis, hi in zip("xyz", (6.0, 4.0, 2.0)):
        table[axis] = rng.uniform(0.1, hi, n)
    table["scale_0"] = table["scale_1"] = table["scale_2"] = -4.0
    table["rot_0"] = 1.0
    table["f_dc_0"] = 0.5
    return table


def _ply(table: np.ndarray, *, fmt: str = "binary_little_endian", count: str | None = None,
         element: str = "vertex", extra_header: str = "") -> bytes:
    props = "".join(f"property float {name}\n" for name in table.dtype.names)
    head = (f"ply\nformat {fmt} 1.0\n{extra_header}element {element} {count or len(table)}\n{props}end_header\n")
    return head.encode() + table.tobytes()


def _with(prop: str, value: float, row: int = 3) -> bytes:
    table = _ply_table()
    table[prop][row] = value
    return _ply(table)


def _without(prop: str) -> bytes:
    table = _ply_table()
    keep = [n for n in table.dtype.names if n != prop]
    return _ply(np.ascontiguousarray(table[keep]).astype([(n, "<f4") for n in keep]))


def _zero_quaternion() -> bytes:
    table = _ply_table()
    table["rot_0"][5] = 0.0
    return _ply(table)


def _f_rest(k: int) -> bytes:
    table = _ply_table()
    names = [*table.dtype.names, *(f"f_rest_{i}" for i in range(k))]
    out = np.zeros(len(table), dtype=[(n, "<f4") for n in names])
    for n in table.dtype.names:
        out[n] = table[n]
    return _ply(out)


GOOD_PLY = _ply(_ply_table())
PLY_CASES: list[tuple[str, bytes, str]] = [
    *[(f"nan-{p}", _with(p, float("nan")), "gaussians.ply: vertex: Gaussian 3 has a non-finite") for p in BASE_PROPS],
    *[(f"inf-{p}", _with(p, float("inf")), "gaussians.ply: vertex: Gaussian 3 has a non-finite")
      for p in ("x", "opacity", "scale_2", "rot_1", "f_dc_2")],
    *[(f"missing-{p}", _without(p), f"gaussians.ply: vertex: missing property {p}") for p in BASE_PROPS],
    ("zero-quaternion", _zero_quaternion(), "gaussians.ply: vertex: Gaussian 5 has a zero rotation quaternion"),
    ("f-rest-5", _f_rest(5), "gaussians.ply: vertex: 5 f_rest properties"),
    ("f-rest-10", _f_rest(10), "gaussians.ply: vertex: 10 f_rest properties"),
    ("no-gaussians", _ply(_ply_table()[:0]), "gaussians.ply: vertex: holds no Gaussians"),
    ("no-magic", b"PLY" + GOOD_PLY[3:], "gaussians.ply: not a PLY file"),
    ("not-ply", b"\x89PNG\r\n", "gaussians.ply: not a PLY file"),
    ("empty", b"", "gaussians.ply: not a PLY file"),
    ("no-end-header", GOOD_PLY.replace(b"end_header", b"end_hdr"), "gaussians.ply: PLY header has no 'end_header'"),
    ("ascii", _ply(_ply_table(), fmt="ascii"), "gaussians.ply: header line 2: only binary_little_endian"),
    ("big-endian", _ply(_ply_table(), fmt="binary_big_endian"), "gaussians.ply: header line 2: only binary_little"),
    ("count-word", _ply(_ply_table(), count="many"), "gaussians.ply: header line 3: cannot parse"),
    ("count-huge", _ply(_ply_table(), count="99999999999"), "gaussians.ply: truncated: element 'vertex' needs"),
    ("no-vertex", _ply(_ply_table(), element="point"), "gaussians.ply: no 'vertex' element"),
    ("list-property", GOOD_PLY.replace(b"property float x\n", b"property list uchar int x\n"),
     "gaussians.ply: header line 4: list properties"),
    ("half-type", GOOD_PLY.replace(b"property float y\n", b"property half y\n"),
     "gaussians.ply: header line 5: unknown property type 'half'"),
    ("stray-line", _ply(_ply_table(), extra_header="hello world\n"), "gaussians.ply: header line 3: cannot parse"),
    ("truncated-1", GOOD_PLY[:-1], "gaussians.ply: truncated: element 'vertex' needs 896 bytes, only 895 left"),
    ("truncated-half", GOOD_PLY[:len(GOOD_PLY) - 448], "gaussians.ply: truncated"),
    ("header-only", GOOD_PLY[:GOOD_PLY.index(b"end_header") + 11], "gaussians.ply: truncated"),
    ("chunk-count", _ply(_ply_table(), extra_header="element chunk 0\n"), "gaussians.ply: chunk: missing properties min_x"),
]


def test_a_good_trained_ply_is_accepted(tiny_scene, run_cli, tmp_path):
    scene = tmp_path / "scene"
    shutil.copytree(tiny_scene, scene)
    (scene / "gaussians.ply").write_bytes(GOOD_PLY)
    code, out, _ = run_cli("check-scene", scene)
    assert code == 0 and "trained gaussians.ply: 16 Gaussians" in out


@pytest.mark.parametrize("data, expect", [c[1:] for c in PLY_CASES], ids=[c[0] for c in PLY_CASES])
def test_damaged_trained_gaussians(data, expect, tiny_scene, run_cli, tmp_path):
    scene = tmp_path / "scene"
    shutil.copytree(tiny_scene, scene)
    (scene / "gaussians.ply").write_bytes(data)
    assert_scene_refused(run_cli, scene, tmp_path, expect)


def test_a_trained_ply_link_leaving_the_scene_is_refused(tiny_scene, run_cli, tmp_path):
    scene = tmp_path / "scene"
    shutil.copytree(tiny_scene, scene)
    (tmp_path / "elsewhere.ply").write_bytes(GOOD_PLY)
    (scene / "gaussians.ply").symlink_to(tmp_path / "elsewhere.ply")
    expect = "gaussians.ply: a link that leaves the scene directory"
    assert_scene_refused(run_cli, scene, tmp_path, expect)


# ---------------------------------------------------------------- a built run: outputs, predictions, run.toml


TS = "scenes/tiny"


def _npz(**changes: Any) -> Callable[[Path], None]:
    def edit(run: Path) -> None:
        path = run / TS / "topdown.npz"
        with np.load(path) as npz:
            arrays = {k: npz[k] for k in npz.files}
        for k, v in changes.items():
            if v is None:
                del arrays[k]
            else:
                arrays[k] = v
        np.savez(path, **arrays)
    return edit


def _smap(edit: Callable[[dict], None]) -> Callable[[Path], None]:
    def apply(run: Path) -> None:
        path = run / TS / "semantic_map.json"
        doc = json.loads(path.read_text())
        edit(doc)
        path.write_text(json.dumps(doc))
    return apply


def _write(rel: str, data: bytes) -> Callable[[Path], None]:
    return lambda run: (run / rel).write_bytes(data)


def _stls(action: str) -> Callable[[Path], None]:
    def apply(run: Path) -> None:
        for p in sorted((run / TS / "colliders").rglob("*.stl"))[:1]:
            p.unlink() if action == "delete" else p.write_bytes(b"solid broken\nfacet\n")
    return apply


def _shard(table_of: Callable[[Any], Any]) -> Callable[[Path], None]:
    def apply(run: Path) -> None:
        import pyarrow.parquet as pq

        path = sorted((run / "episodes/tiny").glob("part-*.parquet"))[0]
        pq.write_table(table_of(pq.read_table(path)), path)
    return apply


def _set_key(doc: dict, keys: tuple, value: Any) -> None:
    node = doc
    for k in keys[:-1]:
        node = node[k]
    node[keys[-1]] = value


GEN = ["gen-trajectories", "{run}", "--per-scene", "2", "--min-geodesic", "1"]
RENDER = ["render", "{run}", "--scene", "tiny", "--pose", "2,2,0", "--out", "{run}/view.png"]
EVAL = ["evaluate", "--run", "{run}", "--predictions", "{run}/baselines/pred.jsonl"]  # inside the run's layout
BASELINE = ["baseline", "--agent", "oracle", "--run", "{run}", "--out", "{run}/b.jsonl"]
VALIDATE = ["validate", "{run}"]

# (case id, damage to a copy of the run, command, what the error line contains)
RUN_CASES: list[tuple[str, Callable[[Path], None], list[str], str]] = [
    ("npz-garbage", _write(f"{TS}/topdown.npz", b"junk"), GEN, "topdown.npz: cannot read"),
    ("npz-empty", _write(f"{TS}/topdown.npz", b""), GEN, "topdown.npz: cannot read"),
    ("npz-nan-origin", _npz(origin=np.array([np.nan, 0.0])), GEN, "topdown.npz: origin: origin must be finite"),
    ("npz-inf-origin", _npz(origin=np.array([0.0, np.inf])), GEN, "topdown.npz: origin: origin must be finite"),
    ("npz-origin-3", _npz(origin=np.zeros(3)), GEN, "topdown.npz: origin: origin must be finite [x, y]"),
    ("npz-negative-resolution", _npz(resolution=np.float64(-1)), GEN, "topdown.npz: origin: "),
    ("npz-nan-resolution", _npz(resolution=np.float64(np.nan)), GEN, "topdown.npz: origin: "),
    ("npz-navigable-1d", _npz(navigable=np.zeros(5, np.uint8)), GEN, "topdown.npz: navigable: navigable (5,)"),
    ("npz-navigable-missing", _npz(navigable=None), GEN, "topdown.npz: navigable: array missing"),
    ("npz-occupancy-missing", _npz(occupancy=None), GEN, "topdown.npz: occupancy: array missing"),
    ("npz-origin-missing", _npz(origin=None), GEN, "topdown.npz: origin: array missing"),
    ("npz-deleted", lambda run: (run / TS / "topdown.npz").unlink(), GEN, "topdown.npz: missing; run `sagebench build-scene` on this run first"),
    ("smap-one-point", _smap(lambda d: _set_key(d, ("instances", 2, "polygon", "coordinates"), [[[[1.0, 1.0]]]])),
     GEN, "semantic_map.json: instances[2].polygon.coordinates: a ring needs at least 4 points"),
    ("smap-open-ring", _smap(lambda d: _set_key(d, ("instances", 2, "polygon", "coordinates"),
                                                [[[[0, 0], [1, 0], [1, 1], [0, 1]]]])),
     GEN, "semantic_map.json: instances[2].polygon.coordinates: a ring needs"),
    ("smap-nan-origin", _write(f"{TS}/semantic_map.json", b""), GEN, "semantic_map.json: Invalid JSON"),
    ("smap-garbage", _write(f"{TS}/semantic_map.json", b"{"), GEN, "semantic_map.json: Invalid JSON"),
    ("smap-origin-nan", _smap(lambda d: _set_key(d, ("origin",), [float("nan"), 0.0])), GEN,
     "semantic_map.json: origin[0]: Input should be a finite number"),
    ("smap-resolution-0", _smap(lambda d: _set_key(d, ("resolution",), 0)), GEN,
     "semantic_map.json: resolution: Input should be greater than 0"),
    ("smap-no-instances", _smap(lambda d: d.pop("instances")), GEN, "semantic_map.json: instances: Field required"),
    ("smap-id-0", _smap(lambda d: _set_key(d, ("instances", 0, "instance_id"), 0)), GEN,
     "semantic_map.json: instances[0].instance_id"),
    ("smap-unknown-room", _smap(lambda d: _set_key(d, ("instances", 2, "room"), "attic")), GEN,
     "semantic_map.json: instances[2].room: room 'attic' is not one of the map's rooms (r0)"),
    ("run-scene-json", _write(f"{TS}/scene.json", b"["), GEN, "tiny/scene.json: malformed JSON"),
    ("render-ply-ascii", _write(f"{TS}/gaussians.ply", b"ply\nformat ascii 1.0\nend_header\n"), RENDER,
     "gaussians.ply: header line 2: only binary_little_endian"),
    ("render-ply-truncated", lambda run: (run / TS / "gaussians.ply").write_bytes(
        (run / TS / "gaussians.ply").read_bytes()[:3000]), RENDER, "gaussians.ply: truncated"),
    ("render-ply-nan", lambda run: (run / TS / "gaussians.ply").write_bytes(_nan_in_run_ply(run)), RENDER,
     "gaussians.ply: vertex: Gaussian 0 has a non-finite position"),
    ("render-out-dir", lambda run: (run / "view.png").mkdir(), RENDER, "view.png: cannot write: Is a directory"),
    ("render-scene-json", _write(f"{TS}/scene.json", b"{}"), RENDER, "tiny/scene.json: scene_id: Field required"),
    ("eval-stl-deleted", _stls("delete"), EVAL, "scene.xml: cannot compile: Error: Error opening file"),
    ("eval-stl-corrupt", _stls("corrupt"), EVAL, "scene.xml: cannot compile: Error:"),
    ("baseline-stl-deleted", _stls("delete"), BASELINE, "scene.xml: cannot compile"),
    ("baseline-stl-corrupt", _stls("corrupt"), BASELINE, "scene.xml: cannot compile"),
    ("validate-stl-deleted", _stls("delete"), VALIDATE, "scene.xml: cannot compile"),
    ("eval-xml-garbage", _write(f"{TS}/scene.xml", b"<mujoco"), EVAL, "scene.xml: cannot load: XML parse error"),
    ("baseline-xml-empty", _write(f"{TS}/scene.xml", b""), BASELINE, "scene.xml: cannot load"),
    ("eval-shard-schema", _shard(lambda t: __import__("pyarrow").table({"a": [1]})), EVAL,
     "-00000.parquet: episode_id: not an episode shard: column missing (has a)"),
    ("eval-shard-type", _shard(lambda t: t.set_column(t.schema.get_field_index("goal_radius"), "goal_radius",
                                                      t.column("goal_radius").cast("string"))), EVAL,
     "-00000.parquet: goal_radius: column type string, expected double"),
    ("eval-shard-dropped", _shard(lambda t: t.drop_columns(["reference_path"])), EVAL,
     "-00000.parquet: reference_path: not an episode shard: column missing"),
    ("baseline-shard-schema", _shard(lambda t: __import__("pyarrow").table({"x": [1.0]})), BASELINE,
     "-00000.parquet: episode_id: not an episode shard"),
    ("eval-shard-garbage", _write("episodes/tiny/part-00000.parquet", b"PAR1junk"), EVAL,
     "episodes/tiny: cannot read episode shards"),
    ("validate-shard-garbage", _write("episodes/tiny/part-00000.parquet", b"junk"), VALIDATE,
     "episodes/tiny: cannot read episode shards"),
    ("eval-out-dir", lambda run: (run / "res").mkdir(), [*EVAL, "--out", "{run}/res"], "res: cannot write: Is a directory"),
    ("build-out-file", lambda run: (run / "afile").write_text("x"), ["build-scene", "{scene}", "--out", "{run}/afile"],
     "afile: is a file, not a run directory: give a folder for the run"),
    ("synth-negative-seed", lambda run: None, ["synth-scene", "--out", "{run}/syn", "--seed", "-1"],
     "--seed: must be 0 or more (got -1)"),
    ("demo-negative-seed", lambda run: None, ["demo", "--out", "{run}/demo", "--seed", "-1"], "--seed: must be 0 or more"),
    ("build-negative-seed", lambda run: None, ["build-scene", "{scene}", "--out", "{run}/o", "--seed", "-1"],
     "--seed: Input should be greater than or equal to 0"),
    ("gen-negative-seed", lambda run: None, [*GEN, "--seed", "-2"], "--seed: Input should be greater than or equal to 0"),
    ("baseline-negative-seed", lambda run: None, ["baseline", "--agent", "random", "--run", "{run}", "--out",
                                                  "{run}/b.jsonl", "--seed", "-5"], "--seed: Input should be greater"),
    ("build-resolution-budget", lambda run: None, ["build-scene", "{scene}", "--out", "{run}/o", "--resolution", "0.0005"],
     "tiny: resolution: a 12005 x 8204 map at 0.0005 m is 98,489,020 cells, over the budget of 25,000,000"),
    ("build-resolution-0", lambda run: None, ["build-scene", "{scene}", "--out", "{run}/o", "--resolution", "0"],
     "--resolution: Input should be greater than 0"),
]


def _nan_in_run_ply(run: Path) -> bytes:
    data = bytearray((run / TS / "gaussians.ply").read_bytes())
    start = data.index(b"end_header\n") + len(b"end_header\n")
    data[start:start + 4] = np.float32(np.nan).tobytes()
    return bytes(data)


def _pred_lines(run: Path) -> list[dict]:
    return [json.loads(line) for line in (run / "baselines" / "oracle.jsonl").read_text().splitlines()]


def _pred(edit: Callable[[list[dict]], Any]) -> Callable[[Path], None]:
    def apply(run: Path) -> None:
        rows = _pred_lines(run)
        out = edit(rows)
        text = out if isinstance(out, str) else "".join(json.dumps(r) + "\n" for r in rows)
        (run / "baselines" / "pred.jsonl").write_text(text)
    return apply


def _row0(**changes: Any) -> Callable[[list[dict]], None]:
    return lambda rows: rows[0].update(changes)


PRED = "pred.jsonl:1: "
PREDICTION_CASES: list[tuple[str, Callable[[Path], None], str]] = [
    ("id-missing", _pred(lambda rows: rows[0].pop("episode_id") and None), PRED + "episode_id: Field required"),
    ("id-empty", _pred(_row0(episode_id="")), PRED + "episode_id: String should have at least 1 character"),
    ("id-number", _pred(_row0(episode_id=7)), PRED + "episode_id: Input should be a valid string"),
    ("id-unknown", _pred(_row0(episode_id="nope")), PRED + "episode_id: unknown episode id 'nope'"),
    ("id-duplicate", _pred(lambda rows: rows[1].update(episode_id=rows[0]["episode_id"])),
     "pred.jsonl:2: episode_id: duplicate episode id"),
    ("poses-empty", _pred(_row0(poses=[])), PRED + "poses: List should have at least 1 item"),
    ("poses-3", _pred(_row0(poses=[[1.0, 2.0, 3.0]])), PRED + "poses[0]: a pose is [x, y, z, yaw]: 4 numbers"),
    ("poses-5", _pred(_row0(poses=[[1.0, 2.0, 3.0, 4.0, 5.0]])), PRED + "poses[0]: Tuple should have at most 4 items"),
    ("poses-string", _pred(_row0(poses=[["1", 2.0, 3.0, 4.0]])), PRED + "poses[0][0]: Input should be a valid number"),
    ("poses-null", _pred(_row0(poses=None)), PRED + "poses: Input should be a valid array"),
    ("poses-nan", _pred(lambda rows: f'{{"episode_id": "{rows[0]["episode_id"]}", "poses": [[NaN, 0, 0, 0]], '
                                      f'"stopped": true}}\n'), PRED + "poses[0][0]"),
    ("poses-flat", _pred(_row0(poses=[1.0, 2.0, 3.0, 4.0])), PRED + "poses[0]: Input should be a valid"),
    ("stopped-string", _pred(_row0(stopped="yes")), PRED + "stopped: Input should be a valid boolean"),
    ("stopped-missing", _pred(lambda rows: rows[0].pop("stopped")), PRED + "stopped: Field required"),
    ("stopped-int", _pred(_row0(stopped=1)), PRED + "stopped: Input should be a valid boolean"),
    ("intensity-2", _pred(lambda rows: rows[0].update(collision_intensity=[2.0] * len(rows[0]["poses"]))),
     PRED + "collision_intensity[0]: Input should be less than or equal to 1"),
    ("intensity-negative", _pred(lambda rows: rows[0].update(collision_intensity=[-0.1] * len(rows[0]["poses"]))),
     PRED + "collision_intensity[0]: Input should be greater than or equal to 0"),
    ("intensity-length", _pred(_row0(collision_intensity=[0.0])), PRED + "collision_intensity has 1 values"),
    ("pose-1e308", _pred(lambda rows: rows[0]["poses"].__setitem__(1, [1e308, 1e308, 0.0, 0.0])),
     PRED + "poses[1]: (1e+308, 1e+308) lies more than 50 m outside the scene's map (x -0.1..6.1, y -0.1..4.2 m)"),
    ("pose-100m-off", _pred(lambda rows: rows[0]["poses"].__setitem__(1, [3.0, -100.0, 0.0, 0.0])),
     PRED + "poses[1]: (3, -100) lies more than 50 m outside the scene's map (x -0.1..6.1, y -0.1..4.2 m)"),
    ("yaw-1e300", _pred(lambda rows: rows[0]["poses"].__setitem__(1, [*rows[0]["poses"][1][:3], 1e300])),
     PRED + "poses[1]: yaw 1e+300 rad is past 100000 either way"),
    ("extra-key", _pred(_row0(confidence=0.5)), PRED + "confidence: Extra inputs are not permitted"),
    ("not-json", _pred(lambda rows: "{episode_id: 1}\n"), PRED + "Invalid JSON"),
    ("json-list", _pred(lambda rows: "[1, 2]\n"), PRED + "Input should be an object"),
    ("nested-deeply", _pred(lambda rows: "[" * 100_000 + "]" * 100_000 + "\n"), "pred.jsonl:1: "),
    ("empty", _pred(lambda rows: ""), "pred.jsonl: no predictions (the file is empty)"),
    ("blank-lines", _pred(lambda rows: "\n\n  \n"), "pred.jsonl: no predictions (the file is empty)"),
    ("missing-rows", _pred(lambda rows: "".join(json.dumps(r) + "\n" for r in rows[1:])),
     "pred.jsonl: 1 of 12 episodes have no prediction"),
    ("not-utf8", lambda run: (run / "baselines" / "pred.jsonl").write_bytes(b"\xff\xfe{}\n"), "pred.jsonl: cannot read"),
    ("a-directory", lambda run: (run / "baselines" / "pred.jsonl").mkdir(), "pred.jsonl: is a directory, not a file"),
    ("deleted", lambda run: None, "pred.jsonl: does not exist"),
]


def _args(template: list[str], run: Path, scene: Path) -> list[str]:
    return [a.format(run=run, scene=scene) for a in template]


@pytest.mark.parametrize("damage, command, expect", [c[1:] for c in RUN_CASES], ids=[c[0] for c in RUN_CASES])
def test_damaged_run_outputs(damage, command, expect, tiny_run, tiny_scene, run_cli, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run, symlinks=True)
    rows = [{k: v for k, v in r.items() if k not in ("collision_intensity", "intensity_source")} for r in _pred_lines(run)]
    (run / "baselines" / "pred.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))  # evaluate replays them
    damage(run)
    assert_refused(run_cli, _args(command, run, tiny_scene), tmp_path, expect)


@pytest.mark.parametrize("damage, expect", [c[1:] for c in PREDICTION_CASES], ids=[c[0] for c in PREDICTION_CASES])
def test_damaged_predictions(damage, expect, tiny_run, run_cli, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run, symlinks=True)
    damage(run)
    assert_refused(run_cli, [*_args(EVAL, run, run), "--out", tmp_path / "scores.json"], tmp_path, expect)


TOML = 'scenes = ["{scene}"]\nout = "out"\n'
TOML_CASES: list[tuple[str, str, str]] = [
    ("malformed", 'scenes = ["{scene}"\n', "run.toml: malformed TOML"),
    ("empty", "", "run.toml: scenes: Field required"),
    ("unknown-key", TOML + "colour = 1\n", "run.toml: colour: Extra inputs are not permitted"),
    ("scenes-empty", 'scenes = []\nout = "out"\n', "run.toml: scenes: List should have at least 1 item"),
    ("scenes-number", 'scenes = [1]\nout = "out"\n', "run.toml: scenes[0]: Input should be a valid string"),
    ("scenes-string", 'scenes = "{scene}"\nout = "out"\n', "run.toml: scenes: Input should be a valid list"),
    ("scenes-nowhere", 'scenes = ["nowhere"]\nout = "out"\n', "run.toml: scenes[0]: 'nowhere' matches no scene"),
    ("scenes-nul", 'scenes = ["a\\u0000b"]\nout = "out"\n', "run.toml: scenes[0]: "),
    ("scenes-glob-nothing", 'scenes = ["none-*"]\nout = "out"\n', "run.toml: scenes[0]: 'none-*' matches no scene"),
    ("out-missing", 'scenes = ["{scene}"]\n', "run.toml: out: Field required"),
    ("workers-0", TOML + "workers = 0\n", "run.toml: workers: Input should be greater than or equal to 1"),
    ("workers-string", TOML + 'workers = "two"\n', "run.toml: workers: Input should be a valid integer"),
    ("executor", TOML + 'executor = "dask"\n', "run.toml: executor: Input should be 'local' or 'ray'"),
    ("seed-negative", TOML + "seed = -1\n", "run.toml: build_scene.seed: Input should be greater than or equal to 0"),
    ("resolution-0", TOML + "[build_scene]\nresolution = 0\n", "run.toml: build_scene.resolution: Input should be"),
    ("resolution-2", TOML + "[build_scene]\nresolution = 2.0\n", "run.toml: build_scene.resolution: Input should be"),
    ("resolution-string", TOML + '[build_scene]\nresolution = "fine"\n', "run.toml: build_scene.resolution: "),
    ("band-inverted", TOML + "[build_scene.agent]\nclearance = 1.0\nheight = 0.5\n",
     "run.toml: build_scene.agent.height: 0.5 must be above the band's bottom, clearance (1.0)"),
    ("band-old-keys", TOML + "[build_scene]\nband_max = 1.5\n", "run.toml: build_scene.band_max: Extra inputs"),
    ("build-unknown", TOML + "[build_scene]\nfoo = 1\n", "run.toml: build_scene.foo: Extra inputs"),
    ("build-seed-negative", TOML + "[build_scene]\nseed = -3\n", "run.toml: build_scene.seed: Input should be"),
    ("per-scene-0", TOML + "[gen_trajectories]\nper_scene = 0\n", "run.toml: gen_trajectories.per_scene: "),
    ("gen-seed-negative", TOML + "[gen_trajectories]\nseed = -1\n", "run.toml: gen_trajectories.seed: "),
    ("gen-unknown", TOML + "[gen_trajectories]\nbar = 1\n", "run.toml: gen_trajectories.bar: Extra inputs"),
    ("export-workers-0", TOML + "[export_usd]\nworkers = 0\n", "run.toml: export_usd.workers: "),
    ("validate-tolerance", TOML + "[validate]\ndepth_tolerance = -1.0\n", "run.toml: validate.depth_tolerance: "),
    ("validate-unknown", TOML + "[validate]\nbaz = 1\n", "run.toml: validate.baz: Extra inputs"),
    ("stage-not-table", TOML + 'build_scene = "fast"\n', "run.toml: build_scene: Input should be"),
]


@pytest.mark.parametrize("text, expect", [c[1:] for c in TOML_CASES], ids=[c[0] for c in TOML_CASES])
def test_damaged_run_toml(text, expect, tiny_scene, run_cli, tmp_path):
    config = tmp_path / "run.toml"
    config.write_text(text.replace("{scene}", str(tiny_scene)))
    assert_refused(run_cli, ["run", config], tmp_path, expect)
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------- the count, and a few as real processes


def test_at_least_250_distinct_damaged_inputs():
    """Distinct inputs by content: scene.json texts, PLY bytes, and the named run / mesh / prediction / toml cases."""
    digests = {hashlib.sha256(text.encode()).hexdigest() for _, text, _ in SCENE_CASES}
    digests |= {hashlib.sha256(b"ply" + data).hexdigest() for _, data, _ in PLY_CASES}
    assert len(digests) == len(SCENE_CASES) + len(PLY_CASES)  # no two cases are the same input
    named = [c[0] for c in MESH_CASES] + list(GLTF_CASES) + [c[0] for c in RUN_CASES] + \
        [c[0] for c in PREDICTION_CASES] + [c[0] for c in TOML_CASES]
    for table in (MESH_CASES, RUN_CASES, PREDICTION_CASES, TOML_CASES):
        assert len({c[0] for c in table}) == len(table)
    assert len(digests) + len(named) >= 250


@pytest.mark.parametrize("case", ["nested-deeply", "scene-id-300", "units-cm"])
def test_real_process_refuses_without_a_traceback(case, tiny_scene, tmp_path):
    scene = tmp_path / "scene"
    shutil.copytree(tiny_scene, scene)
    text, expect = next(c[1:] for c in SCENE_CASES if c[0] == case)
    (scene / "scene.json").write_text(text)
    proc = subprocess.run([sys.executable, "-m", "sagebench", "build-scene", str(scene), "--out", str(tmp_path / "run")],
                          capture_output=True, text=True, timeout=120, env={**os.environ, "PYTHONWARNINGS": "ignore"})
    assert (proc.returncode, proc.stdout, len(proc.stderr.splitlines())) == (2, "", 1), proc.stderr
    assert expect in proc.stderr and not (tmp_path / "run").exists()


def test_debug_shows_the_traceback(tiny_scene, tmp_path):
    scene = tmp_path / "scene"
    shutil.copytree(tiny_scene, scene)
    (scene / "scene.json").write_text(json.dumps(_top(units="cm")))
    proc = subprocess.run([sys.executable, "-m", "sagebench", "--debug", "check-scene", str(scene)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode != 0 and "Traceback" in proc.stderr and "SceneError" in proc.stderr


# ---------------------------------------------------------------- properties: any corruption is a DataError or a valid read


@settings(max_examples=examples(150))
@given(st.lists(st.tuples(st.integers(0, len(GOOD_PLY) - 1), st.integers(0, 255)), min_size=1, max_size=8),
       st.integers(0, len(GOOD_PLY)))
def test_any_corrupted_ply_reads_finite_or_raises_one_data_error(flips, keep):
    """Overwrite bytes of a good PLY and cut it anywhere: read_ply gives finite Gaussians or one DataError line."""
    from sagebench.errors import DataError
    from sagebench.splats.ply import read_ply

    data = bytearray(GOOD_PLY)
    for at, value in flips:
        data[at] = value
    path = Path(tempfile.mkdtemp()) / "gaussians.ply"
    path.write_bytes(bytes(data[:keep]))
    try:
        g = read_ply(path)
    except DataError as err:
        assert "\n" not in str(err) and str(err).startswith(str(path))
    else:
        assert all(np.isfinite(a).all() for a in (g.means, g.quats_wxyz, g.log_scales, g.opacity_logits, g.sh))
    finally:
        shutil.rmtree(path.parent)


@settings(max_examples=examples(200))
@given(st.sampled_from(_leaves(SPEC)), st.one_of(st.none(), st.booleans(), st.integers(), st.floats(),
                                                 st.text(max_size=20), st.lists(st.integers(), max_size=3)))
def test_any_leaf_value_parses_or_raises_one_scene_error(leaf, value):
    """Any JSON value at any leaf of scene.json: a valid spec or one SceneError line starting with the file."""
    from sagebench.errors import SceneError
    from sagebench.scene.loader import parse_spec

    loc, _ = leaf
    text = json.dumps(_set(SPEC, loc, value))
    try:
        parse_spec(text, "scene.json")
    except SceneError as err:
        assert "\n" not in str(err) and str(err).startswith("scene.json: ")


def test_a_full_disk_is_one_line_and_leaves_nothing(tiny_scene, run_cli, tmp_path, monkeypatch):
    import errno

    import sagebench.fileio

    def full(fd: int) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(sagebench.fileio.os, "fsync", full)
    assert_refused(run_cli, ["build-scene", tiny_scene, "--out", tmp_path / "run"], tmp_path,
                   "cannot write: No space left on device")
