"""`sagebench export-usd`: a tiny hand-made run and the demo run, read back with pxr and MuJoCo."""

from __future__ import annotations

import hashlib
import json
import math
import shutil
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from pxr import Usd, UsdGeom, UsdPhysics, UsdSemantics, UsdValidation, UsdVol

from sagebench.collider_export.bodies import DOOR_FLOOR_GAP_M
from sagebench.collider_export.coacd_cache import CACHE_SUBDIR
from sagebench.render.gaussians import Gaussians
from sagebench.scene.loader import door_pose, load_scene
from sagebench.settings.build_scene import BuildSceneConfig, SplatConfig
from sagebench.stages.build_scene import build_scene
from sagebench.splats.ply import read_ply, write_ply
from tests.test_collider_convex import u_prism
from signals import as_from_a_terminal
from tests.test_usd_writer import nvidia_failures

FAST = ["--colliders", "quality", "--coacd-preprocess", "off", "--coacd-max-hulls", "8"]
WALL_X = 4.0  # inner face of the east wall


def _box(size, centre) -> trimesh.Trimesh:
    return trimesh.creation.box(size).apply_translation(centre)


def _gaussians(counts: dict[int, int], seed: int = 0) -> Gaussians:
    rng = np.random.default_rng(seed)
    ids = np.concatenate([np.full(n, i, np.int32) for i, n in counts.items()])
    n = len(ids)
    return Gaussians(rng.normal(size=(n, 3)).astype(np.float32), np.tile(np.float32([1, 0, 0, 0]), (n, 1)),
                     np.full((n, 3), -4.0, np.float32), np.zeros(n, np.float32),
                     rng.normal(size=(n, 1, 3)).astype(np.float32), ids)


def write_tiny_scene(src: Path) -> None:
    """Floor, east wall, a two-box chair, a U-shaped planter (concave: CoACD) and an open door."""
    meshes = {
        "meshes/floor.ply": _box((4, 3, 0.05), (2, 1.5, -0.025)),
        "meshes/wall.ply": _box((0.1, 3, 2.7), (WALL_X + 0.05, 1.5, 1.35)),
        "meshes/chair.ply": trimesh.util.concatenate([_box((0.5, 0.5, 0.05), (0, 0, 0.45)),
                                                      _box((0.05, 0.05, 0.45), (0.2, 0.2, 0.225))]),
        "meshes/planter.obj": u_prism(),
        "meshes/door.ply": _box((0.9, 0.04, 2.0), (0, 0, 1.0)),
    }
    for rel, mesh in meshes.items():
        (src / rel).parent.mkdir(parents=True, exist_ok=True)
        mesh.export(src / rel)
    spec = {
        "scene_id": "tiny", "units": "m", "up_axis": "Z",
        "rooms": [{"id": "room_0", "type": "kitchen", "polygon": [[0, 0], [4, 0], [4, 3], [0, 3]]}],
        "objects": [
            {"instance_id": 1, "category": "floor", "kind": "floor", "mesh": "meshes/floor.ply", "room_id": "room_0"},
            {"instance_id": 2, "category": "wall", "kind": "wall", "mesh": "meshes/wall.ply",
             "attributes": {"colour": "white"}},
            {"instance_id": 3, "category": "chair", "mesh": "meshes/chair.ply", "room_id": "room_0",
             "transform": {"translation": [1.0, 1.0, 0.0], "rotation_wxyz": [0.9238795, 0, 0, 0.3826834]},
             "attributes": {"colour": "red", "material": "wood"}},
            {"instance_id": 4, "category": "planter", "mesh": "meshes/planter.obj", "room_id": "room_0",
             "transform": {"translation": [2.0, 1.5, 0.0]}},
            {"instance_id": 5, "category": "door", "kind": "door", "mesh": "meshes/door.ply", "room_id": "room_0",
             "transform": {"translation": [0.6, 0.2, 0.0]},
             "door": {"state": "open", "hinge": [0.15, 0.2, 0.0], "swing": 1}},
        ],
    }
    (src / "scene.json").write_text(json.dumps(spec))


COUNTS = {0: 4, 1: 10, 2: 11, 3: 12, 4: 13, 5: 14}
FEW_GAUSSIANS = BuildSceneConfig(splats=SplatConfig(object_density=1.0, structure_density=1.0))


def make_run(tmp_path: Path, counts: dict[int, int] = COUNTS) -> Path:
    """The tiny scene built (its maps record the agent's band, which export-usd judges colliders in), with
    `counts` Gaussians per instance id in place of the sampled ones."""
    src, run = tmp_path / "src", tmp_path / "run"
    write_tiny_scene(src)
    build_scene(src, run, FEW_GAUSSIANS)
    write_ply(run / "scenes" / "tiny" / "gaussians.ply", _gaussians(counts))
    return run


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The tiny run exported twice with one cache: (run dir, first stdout, second stdout, file hashes of each)."""
    from sagebench.cli import main

    tmp = tmp_path_factory.mktemp("tiny")
    run, cache = make_run(tmp), tmp / "cache"
    hashes = []
    for _ in range(2):
        with pytest.raises(SystemExit) as exc:
            main(["export-usd", str(run), "--cache-dir", str(cache), "--usdz", *FAST])
        assert exc.value.code in (0, None)
        hashes.append(_hashes(run / "scenes" / "tiny"))
    return run, hashes


def _hashes(d: Path) -> dict[str, str]:
    return {p.relative_to(d).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(d.rglob("*"))
            if p.is_file()}


def test_cold_then_warm_cache_and_messages(tmp_path, run_cli):
    run = make_run(tmp_path)
    code, out, _ = run_cli("export-usd", run, "--cache-dir", tmp_path / "cache", *FAST)
    assert code == 0
    assert "tiny: 5 objects" in out and "pieces: coacd 1; 0 cached" in out and "64 Gaussians" in out
    code, out, _ = run_cli("export-usd", run, "--scene", "tiny", "--cache-dir", tmp_path / "cache", *FAST)
    assert code == 0 and "pieces: coacd 1; 1 cached" in out


def test_outputs_are_byte_identical_on_a_rerun(tiny):
    _, (first, second) = tiny
    assert first == second
    assert {"scene.usda", "geometry.usdc", "scene.usdz", "scene.xml", "colliders/colliders.json",
            "colliders/planter_4/part_000.stl"} <= set(first)


def test_usd_objects_semantics_gaussians_and_transforms(tiny):
    run, _ = tiny
    scene = load_scene(run / "scenes" / "tiny")
    stage = Usd.Stage.Open(str(run / "scenes" / "tiny" / "scene.usda"))
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0 and UsdGeom.GetStageUpAxis(stage) == "Z"
    cache = UsdGeom.XformCache()
    for obj in scene.spec.objects:
        prim = stage.GetPrimAtPath(f"/World/Objects/{obj.category}_{obj.instance_id}")
        assert prim.GetAttribute("sagebench:instanceId").Get() == obj.instance_id
        assert UsdSemantics.LabelsAPI(prim, "class").GetLabelsAttr().Get() == [obj.category]
        field = UsdVol.ParticleField3DGaussianSplat(prim.GetChild("Gaussians"))
        assert len(field.GetPositionsAttr().Get()) == COUNTS[obj.instance_id]
        # the colliders, placed by the stage's transforms, span the scene's world mesh
        pts = []
        for part in prim.GetChild("Colliders").GetChildren():
            assert UsdGeom.Imageable(part).ComputeVisibility() == "invisible"
            assert part.HasAPI(UsdPhysics.CollisionAPI) and part.HasAPI(UsdPhysics.MeshCollisionAPI)
            m = np.array(cache.GetLocalToWorldTransform(part)).T
            p = np.array(UsdGeom.Mesh(part).GetPointsAttr().Get(), dtype=np.float64)
            pts.append(p @ m[:3, :3].T + m[:3, 3])
        bounds = scene.meshes[obj.instance_id].bounds.copy()
        if obj.door is not None:  # a door leaf's colliders clear the floor
            bounds[0, 2] += DOOR_FLOOR_GAP_M
        assert np.allclose(trimesh.PointCloud(np.concatenate(pts)).bounds, bounds, atol=1e-5)
        expect = obj.transform.as_matrix() if obj.door is None else door_pose(obj.door) @ obj.transform.as_matrix()
        assert np.allclose(np.array(cache.GetLocalToWorldTransform(prim)).T, expect, atol=1e-9)
    assert stage.GetPrimAtPath("/World/Objects/chair_3").HasAPI(UsdPhysics.RigidBodyAPI)
    assert not stage.GetPrimAtPath("/World/Objects/planter_4").HasAPI(UsdPhysics.RigidBodyAPI)
    assert stage.GetPrimAtPath("/World/Objects/door_5/Hinge").IsA(UsdPhysics.RevoluteJoint)
    assert len(stage.GetPrimAtPath("/World/Background/Gaussians").GetAttribute("positions").Get()) == COUNTS[0]
    ctx = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators())
    errors = [e.GetMessage() for e in ctx.Validate(stage) if e.GetType() == UsdValidation.ValidationErrorType.Error]
    assert errors == []
    assert nvidia_failures(stage) == []


def test_usdz_package_opens_with_the_same_gaussians(tiny):
    run, _ = tiny
    stage = Usd.Stage.Open(str(run / "scenes" / "tiny" / "scene.usdz"))
    field = UsdVol.ParticleField3DGaussianSplat(stage.GetPrimAtPath("/World/Objects/chair_3/Gaussians"))
    assert len(field.GetPositionsAttr().Get()) == COUNTS[3]
    assert nvidia_failures(stage) == []


def test_export_without_usdz_removes_a_stale_package(tmp_path, run_cli):
    run = make_run(tmp_path)
    scene_dir = run / "scenes" / "tiny"
    assert run_cli("export-usd", run, "--cache-dir", tmp_path / "cache", "--usdz", *FAST)[0] == 0
    assert (scene_dir / "scene.usdz").is_file()
    assert run_cli("export-usd", run, "--cache-dir", tmp_path / "cache", *FAST)[0] == 0
    assert not (scene_dir / "scene.usdz").exists() and (scene_dir / "geometry.usdc").is_file()


def test_mujoco_loads_and_rays_hit_known_surfaces(tiny):
    run, _ = tiny
    m = mujoco.MjModel.from_xml_path(str(run / "scenes" / "tiny" / "scene.xml"))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    geom = np.zeros(1, np.int32)

    def ray(origin, direction):
        dist = mujoco.mj_ray(m, d, np.array(origin, float), np.array(direction, float), None, 1, -1, geom)
        return dist, m.geom(geom[0]).name

    dist, name = ray((1.0, 2.5, 1.0), (1.0, 0.0, 0.0))
    assert name.startswith("wall_2_") and dist == pytest.approx(WALL_X - 1.0, abs=0.02)
    # down the U's notch (x 2.15..2.45, open towards +y) to its base bar at y = 1.6: CoACD parts, not a hull
    dist, name = ray((2.3, 2.5, 0.15), (0.0, -1.0, 0.0))
    assert name.startswith("planter_4_") and dist == pytest.approx(0.9, abs=0.02)


def mjcf_matches_usd(stage, model) -> tuple[int, int]:
    """Assert that the MJCF's joints and masses are the USD stage's; returns (free bodies, hinges). MuJoCo's
    XML writer keeps 6 significant digits, so angles and positions agree to a relative 1e-5."""
    free = hinges = 0
    for prim in stage.GetPrimAtPath("/World/Objects").GetChildren():
        body = model.body(prim.GetName())
        joints = [model.joint(j) for j in range(model.njnt) if model.jnt_bodyid[j] == body.id]
        if not prim.HasAPI(UsdPhysics.RigidBodyAPI):
            assert joints == [], prim.GetName()
            continue
        assert body.mass[0] == pytest.approx(UsdPhysics.MassAPI(prim).GetMassAttr().Get(), rel=1e-5)
        hinge = prim.GetChild("Hinge")
        (joint,) = joints
        if not hinge.IsValid():
            assert joint.type == mujoco.mjtJoint.mjJNT_FREE
            free += 1
            continue
        usd = UsdPhysics.RevoluteJoint(hinge)
        assert joint.type == mujoco.mjtJoint.mjJNT_HINGE and np.allclose(joint.axis, [0, 0, 1])
        lo, hi = np.radians([usd.GetLowerLimitAttr().Get(), usd.GetUpperLimitAttr().Get()])
        assert np.allclose(joint.range, [lo, hi], rtol=1e-5) and joint.limited[0]
        state = math.radians(hinge.GetAttribute("sagebench:stateAngleDeg").Get())
        assert model.qpos0[joint.qposadr[0]] == pytest.approx(state, rel=1e-5, abs=1e-9)
        assert np.allclose(model.jnt_pos[joint.id], usd.GetLocalPos0Attr().Get(), rtol=1e-5)  # the hinge, world frame
        hinges += 1
    return free, hinges


def test_mjcf_joints_and_masses_match_the_usd_stage(tiny):
    run, _ = tiny
    stage = Usd.Stage.Open(str(run / "scenes" / "tiny" / "scene.usda"))
    model = mujoco.MjModel.from_xml_path(str(run / "scenes" / "tiny" / "scene.xml"))
    assert mjcf_matches_usd(stage, model) == (1, 1)  # the chair, the door


def test_colliders_index_lists_every_part(tiny):
    run, _ = tiny
    index = json.loads((run / "scenes" / "tiny" / "colliders" / "colliders.json").read_text())
    by_id = {o["instance_id"]: o for o in index["objects"]}
    assert by_id[3]["exact_parts"] == 2 and by_id[3]["concave_pieces"] == []
    assert [p["method"] for p in by_id[4]["concave_pieces"]] == ["coacd"] and len(by_id[4]["parts"]) >= 3
    assert by_id[3]["quality"] is None  # exact pieces only: the collider is the mesh
    q = by_id[4]["quality"]
    assert q["band_over_cm"] <= 2.0 and q["band_under_cm"] <= 2.0 and q["from_source_max_cm"] <= 1.0
    for obj in index["objects"]:
        for rel in obj["parts"]:
            assert trimesh.load(run / "scenes" / "tiny" / "colliders" / rel).is_watertight


@pytest.mark.parametrize("band_max, method", [(None, "hull"), ("1.9", "voxel")])
def test_colliders_are_judged_in_the_band_the_map_was_built_for(tmp_path, run_cli, band_max, method):
    """An L-shaped shelf from 1.3 to 1.8 m above the floor: above the default agent's 1.2 m its hull blocks nobody,
    so export keeps the hull; for a 1.9 m tall agent (build-scene --band-max 1.9) the hull would block the L's
    notch, so export decomposes it (the band reaches the collider check through the map)."""
    from tests.test_collider_quality import L_SHAPE

    src = tmp_path / "src"
    (src / "meshes").mkdir(parents=True)
    _box((3, 3, 0.05), (1.5, 1.5, -0.025)).export(src / "meshes" / "floor.ply")
    L_SHAPE.copy().apply_scale((1, 1, 0.5)).apply_translation((0.5, 0.5, 1.3)).export(src / "meshes" / "shelf.ply")
    (src / "scene.json").write_text(json.dumps({"scene_id": "shelf", "objects": [
        {"instance_id": 1, "category": "floor", "kind": "floor", "mesh": "meshes/floor.ply"},
        {"instance_id": 2, "category": "shelf", "mesh": "meshes/shelf.ply"}]}))
    build = ["--object-density", "1", "--structure-density", "1"] + (["--band-max", band_max] if band_max else [])
    assert run_cli("build-scene", src, "--out", tmp_path / "run", *build)[0] == 0
    code, _, err = run_cli("export-usd", tmp_path / "run", "--cache-dir", tmp_path / "cache", "--colliders", "balanced")
    assert code == 0, err
    index = json.loads((tmp_path / "run" / "scenes" / "shelf" / "colliders" / "colliders.json").read_text())
    (shelf,) = [o for o in index["objects"] if o["instance_id"] == 2]
    assert [p["method"] for p in shelf["concave_pieces"]] == [method]
    assert shelf["quality"]["band_over_cm"] <= 2.0 and shelf["quality"]["band_under_cm"] <= 2.0


def test_without_gaussians_the_stage_still_gets_colliders(tmp_path, run_cli):
    run = make_run(tmp_path)
    (run / "scenes" / "tiny" / "gaussians.ply").unlink()
    code, out, err = run_cli("export-usd", run, "--cache-dir", tmp_path / "cache", *FAST)
    assert code == 0 and "0 Gaussians" in out
    assert "gaussians.ply: not found; the stage gets colliders and semantics but no Gaussians" in err


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--scene", "nope"], "run: no scenes/nope/scene.json (scenes found: tiny); "
                              "run `sagebench build-scene` on this run first"),
        (["--coacd-threshold", "0"], "error: --coacd-threshold: Input should be greater than 0"),
        (["--coacd-preprocess", "maybe"], "error: --coacd-preprocess: Input should be 'auto', 'on' or 'off'"),
        (["--workers", "0"], "error: --workers: Input should be greater than or equal to 1"),
        (["--gaussians", "splats"], "error: --gaussians: Input should be 'particlefield' or 'nurec'"),
        (["--layout", "sage"], "error: --layout: sage needs --gaussians nurec: SAGE-3D's template references a "
                               "NuRec USDZ"),
    ],
)
def test_bad_options_exit_2_and_write_nothing(tmp_path, run_cli, args, message):
    run = make_run(tmp_path)
    before = _hashes(run)
    code, _, err = run_cli("export-usd", run, "--cache-dir", tmp_path / "cache", *args)
    assert code == 2 and message in err
    assert _hashes(run) == before


def test_run_without_scenes_is_an_error(tmp_path, run_cli):
    code, _, err = run_cli("export-usd", tmp_path, "--cache-dir", tmp_path / "cache")
    assert code == 2
    assert err == (f"error: {tmp_path}: no scenes/<scene_id>/scene.json (scenes found: none); "
                   f"run `sagebench build-scene` on this run first\n")


def test_gaussians_of_an_unknown_object_are_an_error(tmp_path, run_cli):
    run = make_run(tmp_path, {**COUNTS, 99: 2})
    before = _hashes(run)
    code, _, err = run_cli("export-usd", run, "--cache-dir", tmp_path / "cache", *FAST)
    assert code == 2
    assert "gaussians.ply: instance_id: instance_id 99 is not an object of scene.json" in err
    assert _hashes(run) == before


def test_demo_scene_exports_with_exact_parts_only(demo_built_run, tmp_path, run_cli):
    """The demo apartment after build-scene: no CoACD needed, every object and Gaussian in the stage."""
    shutil.copytree(demo_built_run / "scenes", tmp_path / "run" / "scenes")
    code, out, _ = run_cli("export-usd", tmp_path / "run", "--cache-dir", tmp_path / "cache")
    assert code == 0 and "(209 exact; pieces: none; 0 cached)" in out  # office chairs on four casters each
    scene_dir = tmp_path / "run" / "scenes" / "demo_apartment_0"
    g = read_ply(scene_dir / "gaussians.ply")
    stage = Usd.Stage.Open(str(scene_dir / "scene.usda"))
    spec = load_scene(scene_dir).spec
    total = 0
    for obj in spec.objects:
        prim = stage.GetPrimAtPath(f"/World/Objects/{obj.category}_{obj.instance_id}")
        assert prim.IsValid()
        splat = prim.GetChild("Gaussians")
        n = len(splat.GetAttribute("positions").Get()) if splat.IsValid() else 0
        assert n == int((g.instance_id == obj.instance_id).sum())
        total += n
    assert total == int((g.instance_id != 0).sum())
    assert nvidia_failures(stage) == []
    masses = {p.GetName(): UsdPhysics.MassAPI(p).GetMassAttr().Get() for p in stage.Traverse()
              if p.HasAPI(UsdPhysics.MassAPI)}
    assert len(masses) == 25 and all(1.0 < m < 60.0 for m in masses.values()), masses  # one person can push each
    model = mujoco.MjModel.from_xml_path(str(scene_dir / "scene.xml"))
    assert model.nbody == len(spec.objects) + 1
    assert mjcf_matches_usd(stage, model) == (18, 7)


def test_ctrl_c_stops_a_cold_export_and_a_rerun_reuses_every_finished_piece(tmp_path, run_cli):
    """Six different U planters, a CoACD run each: SIGINT once the first is cached; the export stops within
    10 s writing no stage, and the rerun reads every piece that was cached back instead of decomposing it."""
    import signal
    import subprocess
    import sys

    src, run, cache = tmp_path / "src", tmp_path / "run", tmp_path / "cache"
    objects = []
    for i in range(6):
        rel = f"meshes/planter_{i}.obj"
        (src / rel).parent.mkdir(parents=True, exist_ok=True)
        u_prism(0.6 + 0.05 * i).export(src / rel)
        objects.append({"instance_id": i + 1, "category": "planter", "mesh": rel, "room_id": "room_0",
                        "transform": {"translation": [1.0 * i, 0.5, 0.0]}})
    (src / "scene.json").write_text(json.dumps({
        "scene_id": "six", "units": "m", "up_axis": "Z",
        "rooms": [{"id": "room_0", "type": "kitchen", "polygon": [[0, 0], [7, 0], [7, 2], [0, 2]]}],
        "objects": objects}))
    build_scene(src, run, FEW_GAUSSIANS)
    args = ["export-usd", str(run), "--cache-dir", str(cache), "--colliders", "quality", "--coacd-max-hulls", "8"]
    pieces = cache / CACHE_SUBDIR  # beside the meshes' splits
    proc = subprocess.Popen([sys.executable, "-m", "sagebench", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, preexec_fn=as_from_a_terminal)
    try:
        for _ in range(2400):  # up to 2 minutes for the first piece on a busy machine
            if any(pieces.rglob("*.npz")) or proc.poll() is not None:
                break
            time.sleep(0.05)
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=10)
    finally:
        proc.kill()
    finished = {p: p.stat().st_mtime_ns for p in pieces.rglob("*.npz")}
    assert proc.returncode != 0 and 1 <= len(finished) < 6
    assert not (run / "scenes" / "six" / "scene.usda").exists()
    code, out, _ = run_cli(*args)
    # six planters' CoACD pieces (quality also makes balanced's, and keeps whichever is closer in the band)
    assert code == 0 and "six: 6 objects" in out and len(list(pieces.rglob("*.npz"))) == 12
    assert {p: p.stat().st_mtime_ns for p in finished} == finished  # read back, never made again


def test_a_piece_no_method_fits_within_its_budgets_is_refused_naming_it_or_named_in_a_warning(tmp_path, run_cli):
    # one part for the U-shaped planter, the last resort's budget too: its hull fills the U, far past the 2 cm
    # tolerance in the agent band
    run = make_run(tmp_path)
    one_part = ["--colliders", "fast", "--max-parts", "1", "--exact-max-parts", "1"]
    before = _hashes(run / "scenes" / "tiny")
    code, out, err = run_cli("-q", "export-usd", run, "--cache-dir", tmp_path / "cache", *one_part)
    (last,) = err.splitlines()
    assert code == 2 and out == ""
    assert last.startswith("error: planter_4: colliders 15.0 cm off in the agent band cover free floor at ")
    assert last.endswith("that the object leaves open (a doorway?): hull parts of its piece meshes/planter.obj "
                         "(concave piece 0) at the 1-part budget (--max-parts); nothing was written")
    assert _hashes(run / "scenes" / "tiny") == before
    # without build-scene's occupancy (a scene whose maps were written by other means) the warning is all there is
    (run / "scenes" / "tiny" / "topdown.npz").unlink()
    code, _, err = run_cli("export-usd", run, "--cache-dir", tmp_path / "cache", *one_part)
    assert code == 0
    (line,) = [x for x in err.splitlines() if "tolerance" in x]
    assert line.startswith("warning: planter_4: colliders ") and line.endswith(
        "over the 2 cm tolerance: hull parts of its piece meshes/planter.obj (concave piece 0) at the 1-part budget "
        "(--max-parts)")
    # the last resort's own budget lets exact voxels fit the U where the 1-part budget cannot
    code, _, err = run_cli("export-usd", run, "--cache-dir", tmp_path / "cache", "--colliders", "fast",
                           "--max-parts", "1")
    assert code == 0 and "tolerance" not in err
    (planter,) = [o for o in json.loads((run / "scenes" / "tiny" / "colliders" / "colliders.json").read_text())[
        "objects"] if o["name"] == "planter_4"]
    assert [p["method"] for p in planter["concave_pieces"]] == ["voxel_exact"]
    assert 1 < len(planter["parts"]) <= 128 and planter["quality"]["band_over_cm"] <= 2.0


def test_nurec_and_sage_layout_then_back_to_particlefields(tmp_path, run_cli):
    run = make_run(tmp_path)
    scene_dir = run / "scenes" / "tiny"
    code, out, err = run_cli("export-usd", run, "--cache-dir", tmp_path / "cache", "--gaussians", "nurec",
                             "--layout", "sage", "--usdz", *FAST)
    assert code == 0, err
    assert {"gaussians.usdz", "sage/tiny.usda", "sage/tiny_collision.usd", "scene.usdz"} <= set(_hashes(scene_dir))
    stage = Usd.Stage.Open(str(scene_dir / "scene.usda"))
    volume = stage.GetPrimAtPath("/World/Gaussians/gauss")
    assert volume.IsA(UsdVol.Volume) and volume.GetAttribute("omni:nurec:isNuRecVolume").Get()
    assert not stage.GetPrimAtPath("/World/Objects/chair_3/Gaussians").IsValid()
    assert not stage.GetPrimAtPath("/World/Background").IsValid()
    crate = Usd.Stage.Open(str(scene_dir / "geometry.usdc"))
    assert not crate.GetPrimAtPath("/Geometry/Gaussians").IsValid()  # the Gaussians are in the NuRec package only
    for path in (scene_dir / "scene.usdz", scene_dir / "sage" / "tiny.usda"):
        opened = Usd.Stage.Open(str(path))
        assert len([p for p in opened.Traverse() if p.IsA(UsdVol.Volume)]) == 1, path
    with zipfile.ZipFile(scene_dir / "gaussians.usdz") as z:  # the PLY's Gaussians, all of them, in file order
        assert z.namelist() == ["default.usda", "gaussians.nurec", "gauss.usda"]
    cli = Path(sys.executable).with_name("omni_asset_validate")
    for rel in ("scene.usda", "scene.usdz", "geometry.usdc", "gaussians.usdz", "sage/tiny.usda",
                "sage/tiny_collision.usd"):
        done = subprocess.run([str(cli), str(scene_dir / rel)], capture_output=True, text=True)
        assert done.returncode == 0, (rel, done.stderr[-2000:])
    assert run_cli("export-usd", run, "--cache-dir", tmp_path / "cache", *FAST)[0] == 0
    files = set(_hashes(scene_dir))
    assert not {"gaussians.usdz", "scene.usdz"} & files and not (scene_dir / "sage").exists()
    stage.Reload()  # the layers stay open in this process: read them again
    assert stage.GetPrimAtPath("/World/Objects/chair_3/Gaussians").IsA(UsdVol.ParticleField3DGaussianSplat)


def test_sage_layout_without_gaussians_is_an_error_and_writes_nothing(tmp_path, run_cli):
    run = make_run(tmp_path)
    (run / "scenes" / "tiny" / "gaussians.ply").unlink()
    before = _hashes(run)
    code, _, err = run_cli("export-usd", run, "--cache-dir", tmp_path / "cache", "--gaussians", "nurec",
                           "--layout", "sage", *FAST)
    assert code == 2 and err.splitlines()[-1] == \
        "error: --layout sage needs the scene's Gaussians (gaussians.ply): run build-scene again"
    assert _hashes(run) == before


def write_open_concave_scene(src: Path) -> None:
    """A room whose furniture is open concave shapes, as artist meshes are: a torus ottoman and a sectional sofa,
    an annulus (0.9..1.05 m radius, 0.7 m tall) with a 0.9 m wide opening and three faces missing."""
    import shapely

    from sagebench.importers.interiorgs_structure import slab

    ring = shapely.Point(0, 0).buffer(1.05, 32).difference(shapely.Point(0, 0).buffer(0.9, 32))
    c = slab(ring.difference(shapely.box(0, -0.45, 2, 0.45)), 0.0, 0.7)
    meshes = {"meshes/floor.ply": _box((5, 4, 0.05), (2.5, 2, -0.025)),
              "meshes/ottoman.ply": trimesh.creation.torus(0.4, 0.12),
              "meshes/sofa.ply": trimesh.Trimesh(c.vertices, c.faces[3:], process=False)}
    for rel, mesh in meshes.items():
        (src / rel).parent.mkdir(parents=True, exist_ok=True)
        mesh.export(src / rel)
    (src / "scene.json").write_text(json.dumps({
        "scene_id": "open", "units": "m", "up_axis": "Z",
        "rooms": [{"id": "room_0", "type": "living_room", "polygon": [[0, 0], [5, 0], [5, 4], [0, 4]]}],
        "objects": [
            {"instance_id": 1, "category": "floor", "kind": "floor", "mesh": "meshes/floor.ply", "room_id": "room_0"},
            {"instance_id": 2, "category": "ottoman", "mesh": "meshes/ottoman.ply", "room_id": "room_0",
             "transform": {"translation": [1.0, 1.0, 0.12]}},
            {"instance_id": 3, "category": "sofa", "mesh": "meshes/sofa.ply", "room_id": "room_0",
             "transform": {"translation": [3.2, 2.2, 0.0]}}]}))


def test_open_concave_furniture_exports_within_the_band_and_replays_clean(tmp_path, run_cli):
    # the open C's voxels merged to the 32-part budget were 26.5 cm off and covered its open middle: no USD at all;
    # exact voxels at the tolerance, within the last resort's budget, fit it
    src, run = tmp_path / "src", tmp_path / "run"
    write_open_concave_scene(src)
    build_scene(src, run, FEW_GAUSSIANS)
    assert run_cli("-q", "gen-trajectories", run, "--per-scene", "6")[0] == 0
    code, out, err = run_cli("export-usd", run, "--cache-dir", tmp_path / "cache", "--colliders", "fast")
    assert code == 0 and "tolerance" not in err, err
    index = {o["name"]: o for o in json.loads((run / "scenes" / "open" / "colliders" / "colliders.json").read_text())[
        "objects"]}
    assert [p["method"] for p in index["sofa_3"]["concave_pieces"]] == ["voxel_exact"]
    assert len(index["sofa_3"]["parts"]) <= 128
    assert max(index[n]["quality"]["band_over_cm"] for n in ("sofa_3", "ottoman_2")) <= 2.0
    model = mujoco.MjModel.from_xml_path(str(run / "scenes" / "open" / "scene.xml"))
    assert model.nmesh == sum(len(o["parts"]) for o in index.values())
    code, out, err = run_cli("validate", run, "--frames-per-scene", "0")
    assert code == 0 and "validate open: 2/2 trajectories pass" in out, out + err
