"""The loader normalises units and up axis, and rejects bad scenes with one clear line."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
import trimesh

from sagebench.errors import MeshError, SceneError
from sagebench.scene.loader import frame_matrix, load_scene, write_normalised_scene


def _write(scene_dir: Path, spec: dict, meshes: dict[str, trimesh.Trimesh | bytes]) -> Path:
    (scene_dir / "meshes").mkdir(parents=True, exist_ok=True)
    for name, mesh in meshes.items():
        data = mesh if isinstance(mesh, bytes) else mesh.export(file_type=Path(name).suffix[1:])
        (scene_dir / name).write_bytes(data if isinstance(data, bytes) else data.encode())
    (scene_dir / "scene.json").write_text(json.dumps(spec))
    return scene_dir


def _one_box_spec(**obj) -> dict:
    base = {"instance_id": 1, "category": "box", "mesh": "meshes/box.ply"}
    return {"scene_id": "tiny", "objects": [base | obj]}


@pytest.fixture
def box_mesh() -> trimesh.Trimesh:
    return trimesh.creation.box(extents=(1.0, 2.0, 0.5))


# ------------------------------------------------------------------ normalisation


def _to_cm_y_up(src: Path, dst: Path) -> None:
    """Rewrite a metre/Z-up scene as its centimetre/Y-up twin (meshes, transforms, hinges, rooms)."""
    spec = json.loads((src / "scene.json").read_text())
    f = frame_matrix("cm", "Y")
    f_inv = np.linalg.inv(f)
    for name in {o["mesh"] for o in spec["objects"]}:
        mesh = trimesh.load(src / name, force="mesh", process=False)
        mesh.apply_transform(f_inv)
        out = dst / name
        out.parent.mkdir(parents=True, exist_ok=True)
        data = mesh.export(file_type=out.suffix[1:])
        out.write_bytes(data if isinstance(data, bytes) else data.encode())
    source = load_scene(src)
    for obj in spec["objects"]:
        loaded = source.object(obj["instance_id"]).transform.as_matrix()
        obj["transform"] = {"matrix": (f_inv @ loaded @ f).tolist()}
        if "door" in obj:
            obj["door"]["hinge"] = (f_inv @ np.array([*obj["door"]["hinge"], 1.0]))[:3].tolist()
    for room in spec["rooms"]:
        room["polygon"] = [[x * 100, 0.0, -y * 100] for x, y in room["polygon"]]
    spec |= {"units": "cm", "up_axis": "Y"}
    (dst / "scene.json").write_text(json.dumps(spec))


def test_cm_y_up_twin_loads_to_the_same_world(demo_scene_dir, tmp_path):
    twin = tmp_path / "twin"
    _to_cm_y_up(demo_scene_dir, twin)
    a, b = load_scene(demo_scene_dir), load_scene(twin)
    assert a.meshes.keys() == b.meshes.keys()
    for iid in a.meshes:
        np.testing.assert_allclose(b.meshes[iid].vertices, a.meshes[iid].vertices, atol=1e-5)
    for ra, rb in zip(a.spec.rooms, b.spec.rooms):
        np.testing.assert_allclose(rb.polygon, ra.polygon, atol=1e-9)
    assert b.spec.units == "m" and b.spec.up_axis == "Z"


def test_y_up_turns_up_into_z(tmp_path, box_mesh):
    spec = _one_box_spec(transform={"translation": [0, 150, 0], "scale": [100, 100, 100]}) | {"units": "cm", "up_axis": "Y"}
    scene = load_scene(_write(tmp_path, spec, {"meshes/box.ply": box_mesh}))
    lo, hi = scene.meshes[1].bounds
    # the box's 200 cm along Y now stands along Z around 1.5 m; its 50 cm along Z lies along -Y
    np.testing.assert_allclose(lo, [-0.5, -0.25, 1.5 - 1.0], atol=1e-9)
    np.testing.assert_allclose(hi, [0.5, 0.25, 1.5 + 1.0], atol=1e-9)


def test_normalised_directory_reloads_identically(demo_scene_dir, tmp_path):
    a = load_scene(demo_scene_dir)
    write_normalised_scene(a, tmp_path / "norm")
    b = load_scene(tmp_path / "norm")
    assert b.spec == a.spec
    for iid in a.meshes:
        np.testing.assert_array_equal(b.meshes[iid].vertices, a.meshes[iid].vertices)


@pytest.mark.parametrize("ext", ["glb", "gltf", "obj", "ply"])
def test_every_mesh_format_loads(tmp_path, box_mesh, ext):
    if ext == "gltf":
        files = box_mesh.export(file_type="gltf")  # dict of file name -> bytes, the .gltf plus its buffers
        (tmp_path / "meshes").mkdir(parents=True)
        for name, data in files.items():
            (tmp_path / "meshes" / name).write_bytes(data)
        _write(tmp_path, _one_box_spec(mesh="meshes/model.gltf"), {})
    else:
        _write(tmp_path, _one_box_spec(mesh=f"meshes/box.{ext}"), {f"meshes/box.{ext}": box_mesh})
    scene = load_scene(tmp_path)
    np.testing.assert_allclose(scene.meshes[1].extents, [1.0, 2.0, 0.5], atol=1e-6)


# ------------------------------------------------------------------ rejections


def _rejects(run_cli, scene_dir: Path, fragment: str) -> None:
    before = sorted(p.relative_to(scene_dir) for p in scene_dir.rglob("*"))
    code, out, err = run_cli("check-scene", scene_dir)
    assert code == 2
    assert fragment in err, err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert out == ""
    assert sorted(p.relative_to(scene_dir) for p in scene_dir.rglob("*")) == before


def test_rejects_malformed_json(run_cli, tmp_path):
    tmp_path.joinpath("scene.json").write_text('{\n  "scene_id": "x",\n  "objects": [,]\n}')
    _rejects(run_cli, tmp_path, "scene.json: malformed JSON at line 3, column 15: Expecting value")


def test_rejects_missing_mesh(run_cli, tmp_path, box_mesh):
    _write(tmp_path, _one_box_spec(mesh="meshes/nope.ply"), {"meshes/box.ply": box_mesh})
    _rejects(run_cli, tmp_path, "scene.json: objects[0].mesh: mesh file 'meshes/nope.ply' does not exist")


def test_rejects_unreadable_mesh(run_cli, tmp_path):
    _write(tmp_path, _one_box_spec(), {"meshes/box.ply": b"ply\nformat binary_little_endian 1.0\nelement vertex 9\n"})
    _rejects(run_cli, tmp_path, "scene.json: objects[0].mesh: cannot read mesh 'box.ply'")


@pytest.mark.parametrize("path", ["../outside.ply", "meshes/../../outside.ply", "/etc/outside.ply"])
def test_rejects_mesh_path_leaving_the_scene(run_cli, tmp_path, box_mesh, path):
    scene = tmp_path / "scene"
    _write(scene, _one_box_spec(mesh=path), {"meshes/box.ply": box_mesh})
    _rejects(run_cli, scene, f"objects[0].mesh: mesh path {path!r} leaves the scene directory")


def test_rejects_symlink_leaving_the_scene(run_cli, tmp_path, box_mesh):
    outside = tmp_path / "outside.ply"
    outside.write_bytes(box_mesh.export(file_type="ply"))
    scene = _write(tmp_path / "scene", _one_box_spec(mesh="meshes/link.ply"), {})
    os.symlink(outside, scene / "meshes" / "link.ply")
    _rejects(run_cli, scene, "mesh path 'meshes/link.ply' is a link that leaves the scene directory")


def test_rejects_duplicate_instance_id(run_cli, tmp_path, box_mesh):
    spec = _one_box_spec()
    spec["objects"].append(dict(spec["objects"][0]))
    _write(tmp_path, spec, {"meshes/box.ply": box_mesh})
    _rejects(run_cli, tmp_path, "objects[1].instance_id: duplicate instance_id 1 (also objects[0])")


def test_rejects_non_finite_vertices(run_cli, tmp_path):
    ply = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n" \
          b"element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n"
    _write(tmp_path, _one_box_spec(), {"meshes/box.ply": ply})
    _rejects(run_cli, tmp_path, "objects[0].mesh: mesh 'box.ply' has non-finite vertex coordinates")


def test_rejects_empty_mesh(run_cli, tmp_path):
    ply = b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\n" \
          b"element face 0\nproperty list uchar int vertex_indices\nend_header\n"
    _write(tmp_path, _one_box_spec(), {"meshes/box.ply": ply})
    _rejects(run_cli, tmp_path, "objects[0].mesh: mesh 'box.ply' has no triangles")


def test_rejects_unknown_kind(run_cli, tmp_path, box_mesh):
    _write(tmp_path, _one_box_spec(kind="sofa"), {"meshes/box.ply": box_mesh})
    _rejects(run_cli, tmp_path, "objects[0].kind: Input should be 'object', 'wall', 'floor', 'ceiling', 'door' or 'window' (got 'sofa')")


def test_rejects_door_without_door_entry(run_cli, tmp_path, box_mesh):
    _write(tmp_path, _one_box_spec(kind="door"), {"meshes/box.ply": box_mesh})
    _rejects(run_cli, tmp_path, "objects[0]: a door needs a 'door' entry with its state (open, closed or ajar)")


def test_rejects_door_without_state(run_cli, tmp_path, box_mesh):
    _write(tmp_path, _one_box_spec(kind="door", door={"hinge": [0, 0, 0]}), {"meshes/box.ply": box_mesh})
    _rejects(run_cli, tmp_path, "objects[0].door.state: Field required")


def test_library_raises_typed_errors(tmp_path, box_mesh):
    with pytest.raises(SceneError, match="no scene.json"):
        load_scene(tmp_path)
    _write(tmp_path, _one_box_spec(mesh="meshes/nope.ply"), {})
    with pytest.raises(MeshError):
        load_scene(tmp_path)


def test_debug_shows_the_traceback(run_cli, tmp_path):
    tmp_path.joinpath("scene.json").write_text("{")
    with pytest.raises(SceneError):
        run_cli("--debug", "check-scene", tmp_path)
