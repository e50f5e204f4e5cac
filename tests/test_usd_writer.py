"""The USD stage read back with pxr: semantics, invisible colliders with physics, Gaussians, transforms, joints."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from pxr import Gf, Usd, UsdGeom, UsdPhysics, UsdSemantics, UsdValidation, UsdVol

from sagebench.collider_export.convex import hull_part
from sagebench.collider_export.usd_writer import DENSITY_KG_M3, StageObject, build_stage, stage_text
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


@pytest.fixture(scope="module")
def stage(tmp_path_factory):
    path = tmp_path_factory.mktemp("usd") / "scene.usda"
    path.write_text(stage_text("tiny", OBJECTS, gaussians(3, 0, degree=0, seed=3)))
    return Usd.Stage.Open(str(path))


def test_stage_metadata_and_physics_scene(stage):
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert stage.GetDefaultPrim().GetPath() == "/World"
    assert stage.GetPrimAtPath("/World/PhysicsScene").IsA(UsdPhysics.Scene)


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
    assert len(background.GetPositionsAttr().Get()) == 3


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


def test_same_inputs_give_the_same_text():
    assert stage_text("tiny", OBJECTS) == stage_text("tiny", OBJECTS)


def test_prim_names_are_valid_identifiers():
    odd = StageObject(9, "tv-stand 2", "object", np.eye(4), [box_part((1, 1, 1))])
    stage = build_stage("odd", [odd])
    assert stage.GetPrimAtPath("/World/Objects/tv_stand_2_9").IsValid()
