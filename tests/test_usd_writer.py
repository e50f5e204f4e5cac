"""The USD stage read back with pxr: semantics, invisible colliders with physics, Gaussians in their crate layer,
transforms, joints; and checked by its consumers' validators (OpenUSD's and NVIDIA's asset validator)."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
import trimesh
from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, UsdSemantics, UsdValidation, UsdVol

from sagebench.collider_export.convex import hull_part
from sagebench.collider_export.bodies import DENSITY_KG_M3
from sagebench.collider_export.usd_writer import StageObject, build_stage, stage_files, usdz_package
from sagebench.render.gaussians import Gaussians
from sagebench.scene.loader import door_pose
from sagebench.scene.model import Door


def box_part(size, centre=(0, 0, 0)):
    return hull_part(trimesh.creation.box(size).apply_translation(centre).vertices)


def gaussians(n: int, instance_id: int, degree: int, seed: int) -> Gaussians:
    rng = np.random.default_rng(seed)
    k = (degree + 1) ** 2
    return Gaussians(
        means=rng.normal(size=(n, 3)).astype(np.float32),
        quats_wxyz=(rng.normal(size=(n, 4)) * 3).astype(np.float32),
        log_scales=rng.uniform(-5, -2, (n, 3)).astype(np.float32),
        opacity_logits=rng.normal(size=n).astype(np.float32),
        sh=rng.normal(size=(n, k, 3)).astype(np.float32),
        instance_id=np.full(n, instance_id, np.int32),
    )


def pose(yaw: float, t) -> np.ndarray:
    m = trimesh.transformations.rotation_matrix(yaw, [0, 0, 1])
    m[:3, 3] = t
    return m


DOOR = Door(state="ajar", hinge=(2.0, 1.0, 0.0), swing=-1, ajar_deg=30.0)
OBJECTS = [
    StageObject(1, "wall", "wall", np.eye(4), [box_part((4, 0.1, 2.7), (2, 0, 1.35))], attributes={"colour": "white"}),
    StageObject(2, "chair", "object", pose(0.7, (1.0, 2.0, 0.0)), [box_part((0.5, 0.5, 0.05), (0, 0, 0.45)),
                box_part((0.05, 0.05, 0.45), (0.2, 0.2, 0.225))], room_id="room_0", room_type="kitchen",
                attributes={"colour": "red", "material": "wood"}, gaussians=gaussians(7, 2, degree=1, seed=1)),
    StageObject(3, "door", "door", door_pose(DOOR) @ pose(0.0, (2.475, 1.0, 0.0)),
                [box_part((0.95, 0.04, 2.05), (0, 0, 1.025))], room_id="room_0", room_type="kitchen", door=DOOR,
                gaussians=gaussians(5, 3, degree=0, seed=2)),
]


def repeated_colours(g: Gaussians) -> Gaussians:
    """`g` with every other Gaussian's DC term the first one's: colours a viewer sees repeat (as sampled
    material colours do), which NVIDIA's validator wants indexed."""
    sh = g.sh.copy()
    sh[::2, 0] = sh[0, 0]
    return Gaussians(g.means, g.quats_wxyz, g.log_scales, g.opacity_logits, sh, g.instance_id)


BACKGROUND = repeated_colours(gaussians(6, 0, degree=0, seed=3))


@pytest.fixture(scope="module")
def stage(tmp_path_factory):
    out = tmp_path_factory.mktemp("usd")
    for name, data in stage_files("tiny", OBJECTS, BACKGROUND).items():
        (out / name).write_bytes(data)
    return Usd.Stage.Open(str(out / "scene.usda"))


def test_stage_metadata_and_physics_scene(stage):
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert stage.GetDefaultPrim().GetPath() == "/World"
    assert stage.GetPrimAtPath("/World/PhysicsScene").IsA(UsdPhysics.Scene)


def test_gravity_is_9_81_m_s2_down_the_stage_up_axis(stage):
    """As a USD physics engine reads it: direction (0, 0, 0) means minus the up axis, magnitude is in stage units."""
    scene = UsdPhysics.Scene(stage.GetPrimAtPath("/World/PhysicsScene"))
    up = {UsdGeom.Tokens.y: (0.0, 1.0, 0.0), UsdGeom.Tokens.z: (0.0, 0.0, 1.0)}[UsdGeom.GetStageUpAxis(stage)]
    direction = np.array(scene.GetGravityDirectionAttr().Get(), dtype=np.float64)
    direction = -np.array(up) if not direction.any() else direction / np.linalg.norm(direction)
    np.testing.assert_allclose(direction, -np.array(up), atol=1e-7)
    magnitude = scene.GetGravityMagnitudeAttr().Get() * UsdGeom.GetStageMetersPerUnit(stage)
    assert magnitude == pytest.approx(9.81, rel=1e-6)


def test_every_object_has_its_semantics(stage):
    for obj in OBJECTS:
        prim = stage.GetPrimAtPath(f"/World/Objects/{obj.category}_{obj.instance_id}")
        assert prim.IsValid()
        assert prim.GetAttribute("sagebench:instanceId").Get() == obj.instance_id
        assert prim.GetAttribute("sagebench:category").Get() == obj.category
        assert UsdSemantics.LabelsAPI(prim, "class").GetLabelsAttr().Get() == [obj.category]
        for key, value in obj.attributes.items():
            assert prim.GetAttribute(f"sagebench:attributes:{key}").Get() == value
        if obj.room_id:
            assert prim.GetAttribute("sagebench:roomId").Get() == obj.room_id
            assert UsdSemantics.LabelsAPI(prim, "room").GetLabelsAttr().Get() == [obj.room_type]
    assert stage.GetPrimAtPath("/World/Objects/door_3").GetAttribute("sagebench:doorState").Get() == "ajar"


def test_colliders_are_invisible_guides_with_physics_and_world_placement(stage):
    cache = UsdGeom.XformCache()
    for obj in OBJECTS:
        group = stage.GetPrimAtPath(f"/World/Objects/{obj.category}_{obj.instance_id}/Colliders")
        parts = group.GetChildren()
        assert len(parts) == len(obj.parts)
        for prim, part in zip(parts, obj.parts):
            img = UsdGeom.Imageable(prim)
            assert img.ComputeVisibility() == UsdGeom.Tokens.invisible
            assert img.ComputePurpose() == UsdGeom.Tokens.guide
            assert prim.HasAPI(UsdPhysics.CollisionAPI)
            assert UsdPhysics.MeshCollisionAPI(prim).GetApproximationAttr().Get() == UsdPhysics.Tokens.convexHull
            to_world = np.array(cache.GetLocalToWorldTransform(prim)).T  # back to column vectors
            pts = np.array(UsdGeom.Mesh(prim).GetPointsAttr().Get(), dtype=np.float64)
            got = pts @ to_world[:3, :3].T + to_world[:3, 3]
            want = trimesh.transform_points(part.vertices, obj.matrix)
            assert np.allclose(got, want, atol=1e-5)


def test_movable_objects_and_doors_are_rigid_bodies_static_ones_not(stage):
    wall = stage.GetPrimAtPath("/World/Objects/wall_1")
    chair = stage.GetPrimAtPath("/World/Objects/chair_2")
    door = stage.GetPrimAtPath("/World/Objects/door_3")
    assert not wall.HasAPI(UsdPhysics.RigidBodyAPI) and not wall.HasAPI(UsdPhysics.MassAPI)
    for prim in (chair, door):
        assert prim.HasAPI(UsdPhysics.RigidBodyAPI) and prim.HasAPI(UsdPhysics.MassAPI)
    volume = 0.5 * 0.5 * 0.05 + 0.05 * 0.05 * 0.45
    assert UsdPhysics.MassAPI(chair).GetMassAttr().Get() == pytest.approx(volume * DENSITY_KG_M3, rel=1e-6)


def test_gaussians_match_the_input_with_activations(stage):
    cache = UsdGeom.XformCache()
    for obj in OBJECTS:
        g = obj.gaussians
        prim = stage.GetPrimAtPath(f"/World/Objects/{obj.category}_{obj.instance_id}/Gaussians")
        if g is None:
            assert not prim.IsValid()
            continue
        field = UsdVol.ParticleField3DGaussianSplat(prim)
        pos = np.array(field.GetPositionsAttr().Get())
        assert len(pos) == g.count
        to_world = np.array(cache.GetLocalToWorldTransform(prim)).T
        assert np.allclose(pos @ to_world[:3, :3].T + to_world[:3, 3], g.means, atol=1e-5)
        assert np.allclose(np.array(field.GetScalesAttr().Get()), np.exp(g.log_scales), rtol=1e-5)
        assert np.allclose(np.array(field.GetOpacitiesAttr().Get()), 1 / (1 + np.exp(-g.opacity_logits)), rtol=1e-5)
        quats = [(q.GetReal(), *q.GetImaginary()) for q in field.GetOrientationsAttr().Get()]
        assert np.allclose(quats, g.quats_wxyz / np.linalg.norm(g.quats_wxyz, axis=1, keepdims=True), atol=1e-6)
        assert field.GetRadianceSphericalHarmonicsDegreeAttr().Get() == g.sh_degree
        coeffs = np.array(field.GetRadianceSphericalHarmonicsCoefficientsAttr().Get())
        assert np.allclose(coeffs, g.sh.reshape(-1, 3))
        lo, hi = np.array(field.GetExtentAttr().Get())
        assert np.all(lo <= pos.min(axis=0)) and np.all(hi >= pos.max(axis=0))
    background = UsdVol.ParticleField3DGaussianSplat(stage.GetPrimAtPath("/World/Background/Gaussians"))
    assert len(background.GetPositionsAttr().Get()) == 6


def test_door_hinge_joint_frames_meet_at_the_hinge_at_the_state_angle(stage):
    joint = UsdPhysics.RevoluteJoint(stage.GetPrimAtPath("/World/Objects/door_3/Hinge"))
    assert joint.GetBody1Rel().GetTargets() == ["/World/Objects/door_3"]
    assert not joint.GetBody0Rel().GetTargets()  # the world
    assert joint.GetAxisAttr().Get() == "Z"
    body = np.array(UsdGeom.XformCache().GetLocalToWorldTransform(stage.GetPrimAtPath("/World/Objects/door_3"))).T
    pos1 = np.array(joint.GetLocalPos1Attr().Get())
    assert np.allclose(body[:3, :3] @ pos1 + body[:3, 3], DOOR.hinge, atol=1e-5)
    assert np.allclose(joint.GetLocalPos0Attr().Get(), DOOR.hinge)
    q = joint.GetLocalRot1Attr().Get()
    rot1 = np.array(Gf.Matrix3d(Gf.Rotation(Gf.Quatd(q.GetReal(), Gf.Vec3d(q.GetImaginary()))))).T
    world1 = body[:3, :3] @ rot1  # frame 1 in the world; frame 0 is the world's axes
    angle = math.degrees(math.atan2(world1[1, 0], world1[0, 0]))
    assert angle == pytest.approx(-30.0, abs=1e-4)  # swing -1, ajar 30 degrees
    assert (joint.GetLowerLimitAttr().Get(), joint.GetUpperLimitAttr().Get()) == (-90.0, 0.0)
    drive = UsdPhysics.DriveAPI(joint.GetPrim(), "angular")
    assert drive.GetTargetPositionAttr().Get() == pytest.approx(-30.0)


def test_validation_reports_no_errors(stage):
    ctx = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators())
    errors = [e for e in ctx.Validate(stage) if e.GetType() == UsdValidation.ValidationErrorType.Error]
    assert errors == [], [e.GetMessage() for e in errors]


def test_prim_names_are_valid_identifiers(tmp_path):
    odd = StageObject(9, "tv-stand 2", "object", np.eye(4), [box_part((1, 1, 1))])
    stage = build_stage(tmp_path, "odd", [odd])
    assert stage.GetPrimAtPath("/World/Objects/tv_stand_2_9").IsValid()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["geometry.usdc", "scene.usda"]


def nvidia_failures(stage) -> list[str]:
    """Failures and errors of NVIDIA's omniverse-asset-validator (its default rules plus the Gaussian splat
    rule VG.035, which it leaves off by default) on `stage`; warnings and infos are allowed."""
    import omni.asset_validator as av

    engine = av.ValidationEngine()
    engine.enable_rule(av.GaussianSplatSchemaChecker)
    issues = engine.validate(stage)
    bad = [i for i in issues if i.severity in (av.IssueSeverity.FAILURE, av.IssueSeverity.ERROR)]
    return [f"{i.requirement.code if i.requirement else i.rule} {i.at}: {i.message}" for i in bad]


def test_nvidia_asset_validator_finds_no_failure(stage):
    assert nvidia_failures(stage) == []


def test_sh_coefficients_are_a_vertex_primvar_with_display_colour(stage):
    field = UsdVol.ParticleField3DGaussianSplat(stage.GetPrimAtPath("/World/Objects/chair_2/Gaussians"))
    sh = UsdGeom.Primvar(field.GetRadianceSphericalHarmonicsCoefficientsAttr())
    assert (sh.GetInterpolation(), sh.GetElementSize()) == ("vertex", 4)  # degree 1
    colour = UsdGeom.PrimvarsAPI(field.GetPrim()).GetPrimvar("displayColor")
    assert colour.GetInterpolation() == "vertex"
    dc = OBJECTS[1].gaussians.sh[:, 0, :]
    assert np.allclose(np.array(colour.ComputeFlattened()), np.clip(0.28209479177387814 * dc + 0.5, 0, 1), atol=1e-6)


def test_display_colours_are_indexed_each_distinct_colour_once(stage):
    colour = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/World/Background/Gaussians")).GetPrimvar("displayColor")
    assert colour.IsIndexed()
    values, indices = np.array(colour.Get()), np.array(colour.GetIndices())
    assert len(values) == 4 and len(np.unique(values, axis=0)) == 4  # 6 Gaussians, 3 of them one colour
    dc = BACKGROUND.sh[:, 0, :]
    assert np.allclose(values[indices], np.clip(0.28209479177387814 * dc + 0.5, 0, 1), atol=1e-6)


def test_gaussians_carry_3dgrut_colour_space_and_sorting_hints(stage):
    for path in ("/World/Objects/chair_2/Gaussians", "/World/Background/Gaussians"):
        prim = stage.GetPrimAtPath(path)
        field = UsdVol.ParticleField3DGaussianSplat(prim)
        assert prim.HasAPI(Usd.ColorSpaceAPI)
        assert Usd.ColorSpaceAPI(prim).GetColorSpaceNameAttr().Get() == "srgb_rec709_display"
        assert field.GetSortingModeHintAttr().Get() == "cameraDistance"
        assert field.GetProjectionModeHintAttr().Get() == "perspective"


def test_semantic_labels_give_class_and_instance_for_segmentation(stage):
    for obj in OBJECTS:
        prim = stage.GetPrimAtPath(f"/World/Objects/{obj.category}_{obj.instance_id}")
        assert UsdSemantics.LabelsAPI(prim, "instance").GetLabelsAttr().Get() == [str(obj.instance_id)]
        assert set(UsdSemantics.LabelsAPI.GetDirectTaxonomies(prim)) >= {"class", "instance"}


def test_every_collider_has_the_physics_material_mujoco_friction(stage):
    from pxr import UsdShade

    from sagebench.collider_export.bodies import FRICTION

    material = UsdPhysics.MaterialAPI(stage.GetPrimAtPath("/World/PhysicsMaterial"))
    assert (material.GetStaticFrictionAttr().Get(), material.GetDynamicFrictionAttr().Get(),
            material.GetRestitutionAttr().Get()) == (FRICTION, FRICTION, 0.0)
    for obj in OBJECTS:
        for prim in stage.GetPrimAtPath(f"/World/Objects/{obj.category}_{obj.instance_id}/Colliders").GetChildren():
            bound, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial("physics")
            assert bound.GetPath() == "/World/PhysicsMaterial"


def test_crate_layer_alone_has_stage_metadata_typed_prims_and_no_subdivision(tmp_path):
    (tmp_path / "geometry.usdc").write_bytes(stage_files("tiny", OBJECTS, BACKGROUND)["geometry.usdc"])
    crate = Usd.Stage.Open(str(tmp_path / "geometry.usdc"))
    assert (UsdGeom.GetStageMetersPerUnit(crate), UsdGeom.GetStageUpAxis(crate)) == (1.0, "Z")
    assert UsdPhysics.GetStageKilogramsPerUnit(crate) == 1.0 and crate.GetDefaultPrim().GetPath() == "/Geometry"
    assert all(p.GetTypeName() for p in crate.Traverse())
    meshes = [UsdGeom.Mesh(p) for p in crate.Traverse() if p.IsA(UsdGeom.Mesh)]
    assert meshes and all(m.GetSubdivisionSchemeAttr().Get() == "none" for m in meshes)


def test_nvidia_asset_validator_cli_exits_0_on_each_usd_file_alone(tmp_path):
    """`omni_asset_validate FILE` (its default rules; warnings count) on scene.usda, scene.usdz and
    geometry.usdc, each given alone, as a user runs it."""
    import subprocess
    import sys

    files = stage_files("tiny", OBJECTS, BACKGROUND)
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    (tmp_path / "scene.usdz").write_bytes(usdz_package(files))
    cli = Path(sys.executable).with_name("omni_asset_validate")
    for name in ("scene.usda", "scene.usdz", "geometry.usdc"):
        run = subprocess.run([str(cli), str(tmp_path / name)], capture_output=True, text=True)
        problems = [line for line in (run.stdout + run.stderr).splitlines() if line.startswith(("WARNING", "ERROR"))]
        assert (run.returncode, problems) == (0, []), name


def test_collider_normals_point_out_of_each_part(stage):
    for obj in OBJECTS:
        for prim in stage.GetPrimAtPath(f"/World/Objects/{obj.category}_{obj.instance_id}/Colliders").GetChildren():
            mesh = UsdGeom.Mesh(prim)
            pts = np.array(mesh.GetPointsAttr().Get(), dtype=np.float64)
            tri = pts[np.array(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)]
            normals = np.array(mesh.GetNormalsAttr().Get())
            assert mesh.GetNormalsInterpolation() == "uniform" and len(normals) == len(tri)
            outward = tri.mean(axis=1) - pts.mean(axis=0)
            assert np.all(np.einsum("ij,ij->i", normals, outward) > 0)
            assert np.allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-6)


def test_root_is_small_text_and_gaussian_arrays_live_in_the_crate_layer(stage):
    root = stage.GetRootLayer()
    assert root.GetFileFormat().formatId == "usda"
    text = root.ExportToString()
    assert "positions" not in text and "sphericalHarmonicsCoefficients" not in text and "points" not in text
    assert "@./geometry.usdc@</Geometry/Gaussians/chair_2>" in text and "@./geometry.usdc@</Geometry/Colliders/chair_2/part_001>" in text
    crate = Sdf.Layer.FindOrOpen(str(Path(root.realPath).with_name("geometry.usdc")))
    assert crate.GetFileFormat().formatId == "usdc"
    assert crate.GetPrimAtPath("/Geometry/Gaussians/chair_2").GetAttributeAtPath(".positions").default is not None


def test_crate_layer_round_trips_the_arrays_exactly(tmp_path):
    """The crate layer alone (no root) gives back every array bit for bit (float32 as written)."""
    files = stage_files("tiny", OBJECTS, BACKGROUND)
    (tmp_path / "geometry.usdc").write_bytes(files["geometry.usdc"])
    crate = Usd.Stage.Open(str(tmp_path / "geometry.usdc"))
    for name, g in (("chair_2", OBJECTS[1].gaussians), ("door_3", OBJECTS[2].gaussians), ("Background", BACKGROUND)):
        field = UsdVol.ParticleField3DGaussianSplat(crate.GetPrimAtPath(f"/Geometry/Gaussians/{name}"))
        assert np.array_equal(np.array(field.GetPositionsAttr().Get()), g.means)
        assert np.array_equal(np.array(field.GetRadianceSphericalHarmonicsCoefficientsAttr().Get()), g.sh.reshape(-1, 3))
        assert np.array_equal(np.array(field.GetScalesAttr().Get()), np.exp(g.log_scales.astype(np.float64)).astype(np.float32))
    for obj in OBJECTS:
        for i, part in enumerate(obj.parts):
            mesh = UsdGeom.Mesh(crate.GetPrimAtPath(f"/Geometry/Colliders/{obj.category}_{obj.instance_id}/part_{i:03d}"))
            assert np.array_equal(np.array(mesh.GetPointsAttr().Get()), part.vertices.astype(np.float32))
            assert np.array_equal(np.array(mesh.GetFaceVertexIndicesAttr().Get()), part.faces.reshape(-1))


STAGE_BYTES = """
import hashlib, sys
sys.path.insert(0, {tests!r})
from test_usd_writer import BACKGROUND, OBJECTS
from sagebench.collider_export.usd_writer import stage_files
for name, data in sorted(stage_files("tiny", OBJECTS, BACKGROUND).items()):
    print(name, hashlib.sha256(data).hexdigest())
"""


def test_stage_bytes_are_the_same_in_two_fresh_processes():
    import subprocess
    import sys

    script = STAGE_BYTES.format(tests=str(Path(__file__).parent))
    runs = [subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True,
                           env={**os.environ, "PYTHONHASHSEED": seed}).stdout for seed in ("1", "2")]
    assert runs[0] == runs[1]
    assert [line.split()[0] for line in runs[0].splitlines()] == ["geometry.usdc", "scene.usda"]


def test_usdz_package_holds_the_root_first_and_opens(tmp_path):
    import zipfile

    path = tmp_path / "scene.usdz"
    path.write_bytes(usdz_package(stage_files("tiny", OBJECTS, BACKGROUND)))
    assert zipfile.ZipFile(path).namelist() == ["scene.usda", "geometry.usdc"]
    stage = Usd.Stage.Open(str(path))
    field = UsdVol.ParticleField3DGaussianSplat(stage.GetPrimAtPath("/World/Objects/chair_2/Gaussians"))
    assert len(field.GetPositionsAttr().Get()) == 7


def test_upholstered_furniture_weighs_a_bulk_density_of_its_parts(tmp_path):
    """An armchair whose parts hold 0.8 x 0.8 x 0.9 m = 0.576 m^3 weighs 0.576 x 70 = 40.3 kg (not 230 kg)."""
    chair = StageObject(4, "armchair", "object", np.eye(4), [box_part((0.8, 0.8, 0.9), (0, 0, 0.45))])
    stage = build_stage(tmp_path, "soft", [chair])
    mass = UsdPhysics.MassAPI(stage.GetPrimAtPath("/World/Objects/armchair_4")).GetMassAttr().Get()
    assert mass == pytest.approx(0.576 * 70.0, rel=1e-6)


def test_usdz_bytes_do_not_depend_on_the_time(monkeypatch):
    # UsdUtils stamps each zip entry with the current time: two packages a few seconds apart must still match
    import io
    import time
    import zipfile

    from sagebench.collider_export.usd_writer import usdz_package

    files = {"scene.usda": b'#usda 1.0\n\ndef Xform "World"\n{\n}\n'}
    first = usdz_package(files)
    time.sleep(2.1)  # DOS times have a 2 s resolution
    second = usdz_package(files)
    assert first == second
    with zipfile.ZipFile(io.BytesIO(first)) as z:
        assert z.testzip() is None and [i.date_time for i in z.infolist()] == [(1980, 1, 1, 0, 0, 0)]
        assert z.read("scene.usda") == files["scene.usda"]


def test_door_drive_is_the_mjcf_servo_in_usd_units(stage):
    from sagebench.collider_export.bodies import DOOR_HOLD_DAMPING_NMS_PER_RAD, DOOR_HOLD_STIFFNESS_NM_PER_RAD

    drive = UsdPhysics.DriveAPI(stage.GetPrimAtPath("/World/Objects/door_3/Hinge"), "angular")
    per_degree = math.pi / 180  # USD's angular drive gains are per degree
    assert drive.GetStiffnessAttr().Get() == pytest.approx(DOOR_HOLD_STIFFNESS_NM_PER_RAD * per_degree)
    assert drive.GetDampingAttr().Get() == pytest.approx(DOOR_HOLD_DAMPING_NMS_PER_RAD * per_degree)


def test_a_hollow_bin_weighs_its_category_typical_mass_not_its_hull_volume(tmp_path):
    """A 0.3 x 0.3 x 0.45 m bin's hull holds 40 l: 16 kg at 400 kg/m^3, beyond a bin's 6 kg: 2 kg instead; a
    chair's 8 kg stays as its density gives it."""
    from sagebench.collider_export.bodies import MASS_RANGE_KG

    objects = [StageObject(4, "trash_bin", "object", np.eye(4), [box_part((0.3, 0.3, 0.45), (0, 0, 0.225))]),
               StageObject(5, "chair", "object", pose(0, (2, 0, 0)), [box_part((0.45, 0.45, 0.1), (0, 0, 0.45))])]
    stage = build_stage(tmp_path, "bins", objects)
    mass = {p.GetName(): UsdPhysics.MassAPI(p).GetMassAttr().Get() for p in stage.GetPrimAtPath("/World/Objects").GetChildren()}
    assert mass["trash_bin_4"] == MASS_RANGE_KG["trash_bin"][1] == 2.0
    assert mass["chair_5"] == pytest.approx(0.45 * 0.45 * 0.1 * 400.0, rel=1e-6)


def test_bodies_overlapping_where_placed_are_filtered_pairs(tmp_path):
    stage = build_stage(tmp_path, "f", OBJECTS, filtered=[("chair_2", "wall_1")])
    rel = UsdPhysics.FilteredPairsAPI(stage.GetPrimAtPath("/World/Objects/chair_2")).GetFilteredPairsRel()
    assert rel.GetTargets() == [Sdf.Path("/World/Objects/wall_1")]
