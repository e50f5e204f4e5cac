"""The USD stage of a scene: per object its semantics, visible 3D Gaussians and invisible convex colliders.

Layout (metres, Z up, defaultPrim /World):

    /World/PhysicsScene
    /World/Objects/<category>_<instance_id>     Xform, its transform = the object's world pose
        Gaussians                               ParticleField3DGaussianSplat (world-frame values; its
                                                xform cancels the object's, so they render in place)
        Colliders                               Xform, purpose guide, invisible
            part_000, part_001, ...             Mesh, CollisionAPI + MeshCollisionAPI convexHull
        Hinge                                   doors only: RevoluteJoint about the hinge
    /World/Background/Gaussians                 Gaussians of no object (instance id 0), if any

Movable categories get RigidBodyAPI + MassAPI on the object Xform; doors too (a joint needs a body);
everything else is a static collider.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from sagebench.collider_export.convex import ConvexPart
from sagebench.render.gaussians import Gaussians
from sagebench.scene.model import Door

MOVABLE_CATEGORIES: frozenset[str] = frozenset(
    {
        "chair", "office_chair", "armchair", "stool", "coffee_table", "side_table", "trash_bin", "plant",
        "floor_lamp", "rug", "box", "cushion", "pillow", "laptop", "toy", "basket", "vase",
    }
)  # furniture a robot may push aside; everything else is static
DENSITY_KG_M3 = 400.0  # mass of a movable object or door leaf = this x the volume of its parts
DOOR_DRIVE_STIFFNESS = 1000.0  # holds a door at its state's angle (per degree, USD physics units)
DOOR_DRIVE_DAMPING = 100.0


@dataclass(frozen=True)
class StageObject:
    """What the stage needs to know about one scene object."""

    instance_id: int
    category: str
    kind: str
    matrix: np.ndarray  # [4, 4] mesh-file frame -> world (doors: posed at their state's angle)
    parts: Sequence[ConvexPart]  # mesh-file frame
    room_id: str | None = None
    room_type: str | None = None
    attributes: Mapping[str, str] = field(default_factory=dict)
    door: Door | None = None  # world frame (hinge in metres)
    gaussians: Gaussians | None = None  # world frame; every one of them belongs to this object


def prim_name(obj: StageObject) -> str:
    from pxr import Tf

    return Tf.MakeValidIdentifier(f"{obj.category}_{obj.instance_id}")


def is_movable(obj: StageObject) -> bool:
    return obj.kind == "object" and obj.category in MOVABLE_CATEGORIES


def build_stage(scene_id: str, objects: Sequence[StageObject], background: Gaussians | None = None):
    """An in-memory Usd.Stage of the scene (see the module docstring for its layout); `background` are the
    Gaussians of no object (instance id 0), written to /World/Background/Gaussians."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics

    stage = Usd.Stage.CreateInMemory(f"{scene_id}.usda")
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdPhysics.SetStageKilogramsPerUnit(stage, 1.0)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    world.GetPrim().SetCustomDataByKey("sagebench:sceneId", scene_id)
    physics = UsdPhysics.Scene.Define(stage, "/World/PhysicsScene")
    physics.CreateGravityDirectionAttr(Gf.Vec3f(0.0, 0.0, -1.0))
    physics.CreateGravityMagnitudeAttr(9.81)
    UsdGeom.Scope.Define(stage, "/World/Objects")
    if background is not None and background.count:
        UsdGeom.Xform.Define(stage, "/World/Background")
        _write_gaussians(stage, Sdf.Path("/World/Background/Gaussians"), background, np.eye(4))
    for obj in objects:
        path = Sdf.Path("/World/Objects").AppendChild(prim_name(obj))
        xform = UsdGeom.Xform.Define(stage, path)
        xform.AddTransformOp().Set(_gf_matrix(obj.matrix))
        _write_semantics(xform.GetPrim(), obj)
        if obj.gaussians is not None:
            _write_gaussians(stage, path.AppendChild("Gaussians"), obj.gaussians, np.linalg.inv(obj.matrix))
        volume = _write_colliders(stage, path.AppendChild("Colliders"), obj.parts) * abs(np.linalg.det(obj.matrix[:3, :3]))
        if is_movable(obj) or obj.door is not None:
            UsdPhysics.RigidBodyAPI.Apply(xform.GetPrim())
            UsdPhysics.MassAPI.Apply(xform.GetPrim()).CreateMassAttr(float(max(volume, 1e-6) * DENSITY_KG_M3))
        if obj.door is not None:
            _write_hinge(stage, path, obj)
    return stage


def stage_text(scene_id: str, objects: Sequence[StageObject], background: Gaussians | None = None) -> str:
    """The stage as .usda text (same inputs give the same text)."""
    stage = build_stage(scene_id, objects, background)  # keep the stage alive: it owns the layer
    return stage.GetRootLayer().ExportToString()


def _gf_matrix(m: np.ndarray):
    from pxr import Gf

    # USD multiplies row vectors: its matrix is the transpose of ours
    return Gf.Matrix4d(np.asarray(m, dtype=np.float64).T.tolist())


def _write_semantics(prim, obj: StageObject) -> None:
    from pxr import Sdf, UsdSemantics

    labels = {"class": obj.category, "kind": obj.kind}
    if obj.room_type:
        labels["room"] = obj.room_type
    for taxonomy, label in labels.items():
        UsdSemantics.LabelsAPI.Apply(prim, taxonomy).CreateLabelsAttr([label])
    prim.CreateAttribute("sagebench:instanceId", Sdf.ValueTypeNames.Int, custom=True).Set(obj.instance_id)
    prim.CreateAttribute("sagebench:category", Sdf.ValueTypeNames.String, custom=True).Set(obj.category)
    prim.CreateAttribute("sagebench:kind", Sdf.ValueTypeNames.String, custom=True).Set(obj.kind)
    if obj.room_id is not None:
        prim.CreateAttribute("sagebench:roomId", Sdf.ValueTypeNames.String, custom=True).Set(obj.room_id)
    for key in sorted(obj.attributes):
        name = f"sagebench:attributes:{_identifier(key)}"
        prim.CreateAttribute(name, Sdf.ValueTypeNames.String, custom=True).Set(obj.attributes[key])
    if obj.door is not None:
        prim.CreateAttribute("sagebench:doorState", Sdf.ValueTypeNames.String, custom=True).Set(obj.door.state)


def _identifier(text: str) -> str:
    from pxr import Tf

    return Tf.MakeValidIdentifier(text)


def _write_gaussians(stage, path, g: Gaussians, world_to_local: np.ndarray) -> None:
    """Author a ParticleField3DGaussianSplat with activated values: unit quaternions, scales in metres
    (exp of the PLY's logs), opacities in [0, 1] (sigmoid of its logits) and SH coefficients point-major
    ([N * K] float3, DC first), positions in world metres (its xform cancels the object's)."""
    from pxr import Gf, UsdGeom, UsdVol, Vt

    prim = UsdVol.ParticleField3DGaussianSplat.Define(stage, path)
    UsdGeom.Xformable(prim.GetPrim()).AddTransformOp().Set(_gf_matrix(world_to_local))
    pos = np.ascontiguousarray(g.means, dtype=np.float32)
    prim.CreatePositionsAttr(Vt.Vec3fArray.FromNumpy(pos))
    q = g.quats_wxyz.astype(np.float64)
    q /= np.maximum(np.linalg.norm(q, axis=1, keepdims=True), 1e-12)
    xyzw = np.ascontiguousarray(q[:, [1, 2, 3, 0]], dtype=np.float32)  # GfQuatf stores the real part last
    prim.CreateOrientationsAttr(Vt.QuatfArray.FromNumpy(xyzw))
    scales = np.exp(g.log_scales.astype(np.float64)).astype(np.float32)
    prim.CreateScalesAttr(Vt.Vec3fArray.FromNumpy(scales))
    opacities = (1.0 / (1.0 + np.exp(-g.opacity_logits.astype(np.float64)))).astype(np.float32)
    prim.CreateOpacitiesAttr(Vt.FloatArray.FromNumpy(opacities))
    prim.CreateRadianceSphericalHarmonicsDegreeAttr(g.sh_degree)
    coeffs = np.ascontiguousarray(g.sh, dtype=np.float32).reshape(-1, 3)
    prim.CreateRadianceSphericalHarmonicsCoefficientsAttr(Vt.Vec3fArray.FromNumpy(coeffs))
    if g.count:
        reach = 3.0 * scales.max(axis=1, keepdims=True)  # 3 sigma around each centre
        lo, hi = (pos - reach).min(axis=0), (pos + reach).max(axis=0)
    else:
        lo = hi = np.zeros(3)
    prim.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]))


def _write_colliders(stage, path, parts: Sequence[ConvexPart]) -> float:
    """Author the invisible collider meshes; returns the total volume of the parts (mesh-file units^3)."""
    from pxr import UsdGeom, UsdPhysics, Vt

    group = UsdGeom.Xform.Define(stage, path)
    group.CreatePurposeAttr(UsdGeom.Tokens.guide)
    group.CreateVisibilityAttr(UsdGeom.Tokens.invisible)
    total = 0.0
    for i, part in enumerate(parts):
        mesh = UsdGeom.Mesh.Define(stage, path.AppendChild(f"part_{i:03d}"))
        points = Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(part.vertices, dtype=np.float32))
        mesh.CreatePointsAttr(points)
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(part.faces)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(part.faces.reshape(-1), dtype=np.int32)))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        mesh.CreateExtentAttr(UsdGeom.PointBased.ComputeExtent(points))
        UsdPhysics.CollisionAPI.Apply(mesh.GetPrim())
        UsdPhysics.MeshCollisionAPI.Apply(mesh.GetPrim()).CreateApproximationAttr(UsdPhysics.Tokens.convexHull)
        total += part.volume
    return total


def _write_hinge(stage, body_path, obj: StageObject) -> None:
    """A revolute joint about the vertical axis through the hinge; angle 0 = closed, held at the state's angle."""
    from pxr import Gf, Sdf, UsdPhysics

    door = obj.door
    angle = math.degrees(door.angle_rad())
    joint = UsdPhysics.RevoluteJoint.Define(stage, body_path.AppendChild("Hinge"))
    joint.CreateBody1Rel().SetTargets([body_path])
    joint.CreateAxisAttr(UsdPhysics.Tokens.z)
    hinge = np.array([*door.hinge, 1.0])
    joint.CreateLocalPos0Attr(Gf.Vec3f(*map(float, hinge[:3])))
    joint.CreateLocalRot0Attr(Gf.Quatf(1.0))
    # frame 1 in the leaf's frame: at the hinge, turned so the joint reads `angle` in the current pose
    local = np.linalg.inv(obj.matrix) @ hinge
    joint.CreateLocalPos1Attr(Gf.Vec3f(*map(float, local[:3])))
    q = _quat_wxyz(_rotation_part(obj.matrix).T @ _rot_z(math.radians(angle)))
    joint.CreateLocalRot1Attr(Gf.Quatf(*q))
    full = door.open_deg * door.swing
    joint.CreateLowerLimitAttr(float(min(0.0, full)))
    joint.CreateUpperLimitAttr(float(max(0.0, full)))
    drive = UsdPhysics.DriveAPI.Apply(joint.GetPrim(), "angular")
    drive.CreateTargetPositionAttr(float(angle))
    drive.CreateStiffnessAttr(DOOR_DRIVE_STIFFNESS)
    drive.CreateDampingAttr(DOOR_DRIVE_DAMPING)
    joint.GetPrim().CreateAttribute("sagebench:stateAngleDeg", Sdf.ValueTypeNames.Float, custom=True).Set(float(angle))


def _rotation_part(m: np.ndarray) -> np.ndarray:
    """[3, 3] rotation of a [4, 4] matrix with its scale (and any shear) removed (polar decomposition)."""
    from scipy.linalg import polar

    rot, _ = polar(np.asarray(m, dtype=np.float64)[:3, :3])
    return rot


def _rot_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _quat_wxyz(rot: np.ndarray) -> tuple[float, float, float, float]:
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(rot).as_quat()
    return (float(w), float(x), float(y), float(z))

