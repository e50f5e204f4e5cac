"""The USD stage of a scene: per object its semantics, visible 3D Gaussians and invisible convex colliders.

Two layers: the root (scene.usda, small text: prims, semantics, physics) and the arrays in a crate
layer (geometry.usdc, defaultPrim /Geometry: Gaussians under /Geometry/Gaussians, collider meshes under
/Geometry/Colliders) that the root's Gaussians and collider prims reference. Each layer carries its own stage
metadata (metres, Z up, kilograms) and its prims' schemas, so each passes NVIDIA's asset validator alone.
Root layout (defaultPrim /World):

    /World/PhysicsScene
    /World/PhysicsMaterial                      Material + PhysicsMaterialAPI, bound (purpose physics) to
                                                every collider group; the friction MJCF's geoms have
    /World/Objects/<category>_<instance_id>     Xform, its transform = the object's world pose; semantics
                                                LabelsAPI "class" (category) and "instance" (instance id)
        Gaussians                               ParticleField3DGaussianSplat referencing
                                                </Geometry/Gaussians/<category>_<instance_id>> of the crate
                                                layer (world-frame values; its xform cancels the object's)
        Colliders                               Xform, purpose guide, invisible
            part_000, part_001, ...             Mesh referencing </Geometry/Colliders/<name>/part_NNN> (points,
                                                face normals, subdivisionScheme none), CollisionAPI +
                                                MeshCollisionAPI convexHull (parts within PhysX's 64 vertices)
        Hinge                                   doors only: RevoluteJoint about the hinge
    /World/Background/Gaussians                 Gaussians of no object (instance id 0), if any

Movable categories get RigidBodyAPI + MassAPI on the object Xform; doors too (a joint needs a body);
everything else is a static collider. The Gaussians follow the layout NVIDIA's asset validator checks
(VG.035): SH coefficients a vertex-interpolated primvar with elementSize (degree + 1)^2, and an indexed
primvars:displayColor from the DC term; like NVIDIA 3DGRUT's ParticleField writer they carry ColorSpaceAPI
(srgb_rec709_display: SH colours are display sRGB), projectionModeHint perspective and sortingModeHint
cameraDistance.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from sagebench.collider_export.bodies import (
    DOOR_HOLD_DAMPING_NMS_PER_RAD, DOOR_HOLD_STIFFNESS_NM_PER_RAD, FRICTION, MIN_VOLUME_M3, RESTITUTION, body_mass,
    is_movable,
)
from sagebench.collider_export.convex import ConvexPart
from sagebench.render.gaussians import Gaussians, dc_rgb
from sagebench.run_layout import USD, USD_GEOMETRY
from sagebench.scene.model import Door

GEOMETRY_ROOT = "/Geometry"  # the crate layer's defaultPrim
GAUSSIANS_ROOT = "/Geometry/Gaussians"  # in the crate layer: one ParticleField3DGaussianSplat per object (and Background)
COLLIDERS_ROOT = "/Geometry/Colliders"  # in the crate layer: <object>/part_NNN, one Mesh per convex part
PHYSICS_MATERIAL = "/World/PhysicsMaterial"
GAUSSIAN_COLOR_SPACE = "srgb_rec709_display"  # what 3DGRUT's writer says of SH colours (gamma-encoded)


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


def is_body(obj: StageObject) -> bool:
    """A rigid body in the exports: movable furniture (free) and doors (on their hinge)."""
    return is_movable(obj.kind, obj.category) or obj.door is not None


def object_mass(obj: StageObject) -> float:
    """kg of a body, from the world volume of its collider parts (the same figure in USD and MJCF)."""
    return body_mass(obj.category, _world_volume(obj))


def object_density(obj: StageObject) -> float:
    """kg/m^3 that gives a body's collider parts its object_mass: what MJCF's geoms take."""
    return object_mass(obj) / max(_world_volume(obj), MIN_VOLUME_M3)


def _world_volume(obj: StageObject) -> float:
    return sum(p.volume for p in obj.parts) * abs(np.linalg.det(obj.matrix[:3, :3]))


def stage_files(scene_id: str, objects: Sequence[StageObject], background: Gaussians | None = None, *,
                nurec: str | None = None, filtered: Sequence[tuple[str, str]] = ()) -> dict[str, bytes]:
    """The stage's files by name: USD (the text root) and USD_GEOMETRY (the crate layer it references).
    Same inputs give the same bytes, in any process. `nurec`, `filtered`: see build_stage."""
    with tempfile.TemporaryDirectory(prefix="sagebench-usd-") as tmp:
        build_stage(Path(tmp), scene_id, objects, background, nurec=nurec, filtered=filtered)
        return {p.name: p.read_bytes() for p in sorted(Path(tmp).iterdir())}


def usdz_package(files: Mapping[str, bytes]) -> bytes:
    """One .usdz holding the stage's files (as `stage_files` gives them), its root layer first."""
    from pxr import UsdUtils

    with tempfile.TemporaryDirectory(prefix="sagebench-usdz-") as tmp:
        for name, data in files.items():
            (Path(tmp) / name).write_bytes(data)
        out = Path(tmp) / "package.usdz"
        if not UsdUtils.CreateNewUsdzPackage(str(Path(tmp) / USD), str(out)):
            raise RuntimeError(f"UsdUtils could not package {USD} as .usdz")
        return _without_zip_times(out.read_bytes())


def _without_zip_times(data: bytes) -> bytes:
    """The zip `data` with every entry's DOS modification time and date set to 1980-01-01 00:00, so the
    package's bytes do not depend on when it was made. Patched in place: the fields have a fixed size, so the
    64-byte alignment usdz requires of each file's data is kept."""
    import struct

    buf = bytearray(data)
    end = buf.rfind(b"PK\x05\x06")
    count, _, cd_offset = struct.unpack_from("<HII", buf, end + 10)
    at = cd_offset
    for _ in range(count):
        name_len, extra_len, comment_len = struct.unpack_from("<HHH", buf, at + 28)
        local = struct.unpack_from("<I", buf, at + 42)[0]
        struct.pack_into("<HH", buf, at + 12, 0, 0x21)  # central header: time, date
        struct.pack_into("<HH", buf, local + 10, 0, 0x21)  # local header: time, date
        at += 46 + name_len + extra_len + comment_len
    return bytes(buf)


def build_stage(directory: Path, scene_id: str, objects: Sequence[StageObject], background: Gaussians | None = None,
                *, nurec: str | None = None, filtered: Sequence[tuple[str, str]] = ()):
    """Write the stage into `directory` (USD and USD_GEOMETRY) and return it opened; `background` are the
    Gaussians of no object (instance id 0), at /World/Background/Gaussians. `nurec`: the name of a NuRec
    USDZ beside the root holding the scene's Gaussians (splats.nurec), referenced at /World/Gaussians
    (its volume at /World/Gaussians/gauss) in place of ParticleFields (objects then carry no Gaussians).
    `filtered`: pairs of object prim names that do not collide (FilteredPairsAPI on the first): MJCF's
    contact exclusions of bodies overlapping where they stand."""
    from pxr import Sdf, Usd, UsdGeom, UsdPhysics

    splats = [(Sdf.Path("/World/Objects").AppendChild(prim_name(o)), o.gaussians, np.linalg.inv(o.matrix))
              for o in objects if o.gaussians is not None and o.gaussians.count]
    if background is not None and background.count:
        splats.insert(0, (Sdf.Path("/World/Background"), background, np.eye(4)))
    crate = Usd.Stage.CreateNew(str(Path(directory) / USD_GEOMETRY))
    stage_metadata(crate)
    for scope in (GEOMETRY_ROOT, *([GAUSSIANS_ROOT] if splats else []), COLLIDERS_ROOT):
        UsdGeom.Scope.Define(crate, scope)
    crate.SetDefaultPrim(crate.GetPrimAtPath(GEOMETRY_ROOT))
    for parent, g, _ in splats:
        _write_gaussian_arrays(crate, _crate_path(parent), g)
    for obj in objects:
        group = Sdf.Path(COLLIDERS_ROOT).AppendChild(prim_name(obj))
        UsdGeom.Scope.Define(crate, group)
        for i, part in enumerate(obj.parts):
            write_mesh_arrays(crate, group.AppendChild(part_name(i)), part)
    crate.GetRootLayer().Save()
    stage = Usd.Stage.CreateNew(str(Path(directory) / USD))
    _author_root(stage, scene_id, objects, splats)
    for a, b in filtered:
        prim = stage.GetPrimAtPath(Sdf.Path("/World/Objects").AppendChild(a))
        UsdPhysics.FilteredPairsAPI.Apply(prim).CreateFilteredPairsRel().AddTarget(
            Sdf.Path("/World/Objects").AppendChild(b))
    if nurec is not None:
        from pxr import UsdUtils

        from sagebench.splats.nurec import GAUSS_LAYER

        gaussians = UsdGeom.Xform.Define(stage, "/World/Gaussians").GetPrim()
        quiet = UsdUtils.CoalescingDiagnosticDelegate()  # the package is written beside the root afterwards
        gaussians.GetReferences().AddReference(f"./{nurec}[{GAUSS_LAYER}]")
        del quiet
    stage.GetRootLayer().Save()
    return stage


def _crate_path(parent):
    from pxr import Sdf

    return Sdf.Path(GAUSSIANS_ROOT).AppendChild(parent.name)


def stage_metadata(stage) -> None:
    """metersPerUnit 1, upAxis Z, kilogramsPerUnit 1: on every layer written, so each is complete alone."""
    from pxr import UsdGeom, UsdPhysics

    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdPhysics.SetStageKilogramsPerUnit(stage, 1.0)


def _author_root(stage, scene_id: str, objects: Sequence[StageObject], splats) -> None:
    from pxr import Gf, Sdf, UsdGeom, UsdPhysics

    stage_metadata(stage)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    world.GetPrim().SetCustomDataByKey("sagebench:sceneId", scene_id)
    physics = UsdPhysics.Scene.Define(stage, "/World/PhysicsScene")
    physics.CreateGravityDirectionAttr(Gf.Vec3f(0.0, 0.0, -1.0))
    physics.CreateGravityMagnitudeAttr(9.81)
    material = physics_material(stage, PHYSICS_MATERIAL)
    UsdGeom.Scope.Define(stage, "/World/Objects")
    if any(parent.name == "Background" for parent, _, _ in splats):
        UsdGeom.Xform.Define(stage, "/World/Background")
    for obj in objects:
        path = Sdf.Path("/World/Objects").AppendChild(prim_name(obj))
        xform = UsdGeom.Xform.Define(stage, path)
        xform.AddTransformOp().Set(gf_matrix(obj.matrix))
        write_semantics(xform.GetPrim(), obj)
        _write_colliders(stage, path.AppendChild("Colliders"), Sdf.Path(COLLIDERS_ROOT).AppendChild(path.name),
                         len(obj.parts), material)
        if is_body(obj):
            UsdPhysics.RigidBodyAPI.Apply(xform.GetPrim())
            UsdPhysics.MassAPI.Apply(xform.GetPrim()).CreateMassAttr(object_mass(obj))
        if obj.door is not None:
            _write_hinge(stage, path, obj)
    for parent, _, world_to_local in splats:
        _reference_gaussians(stage, parent.AppendChild("Gaussians"), _crate_path(parent), world_to_local)


def gf_matrix(m: np.ndarray):
    from pxr import Gf

    # USD multiplies row vectors: its matrix is the transpose of ours
    return Gf.Matrix4d(np.asarray(m, dtype=np.float64).T.tolist())


def write_semantics(prim, obj: StageObject) -> None:
    from pxr import Sdf, UsdSemantics

    labels = {"class": obj.category, "instance": str(obj.instance_id), "kind": obj.kind}
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


def _reference_gaussians(stage, path, crate_path, world_to_local: np.ndarray) -> None:
    """The root's Gaussians prim: a reference to its arrays in the crate layer, and the xform that puts
    their world-frame values back in place under the object's transform."""
    from pxr import UsdGeom, UsdVol

    prim = UsdVol.ParticleField3DGaussianSplat.Define(stage, path).GetPrim()
    prim.GetReferences().AddReference(f"./{USD_GEOMETRY}", crate_path)
    UsdGeom.Xformable(prim).AddTransformOp().Set(gf_matrix(world_to_local))


def _write_gaussian_arrays(stage, path, g: Gaussians) -> None:
    """Author a ParticleField3DGaussianSplat in the crate `stage` with activated values: unit quaternions, scales in
    metres (exp of the PLY's logs), opacities in [0, 1] (sigmoid of its logits), SH coefficients
    point-major ([N * K] float3, DC first; a vertex primvar of elementSize K) and displayColor from the
    DC term, positions in world metres."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdVol, Vt

    prim = UsdVol.ParticleField3DGaussianSplat.Define(stage, path)
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
    sh = UsdGeom.Primvar(prim.CreateRadianceSphericalHarmonicsCoefficientsAttr(Vt.Vec3fArray.FromNumpy(coeffs)))
    sh.SetInterpolation(UsdGeom.Tokens.vertex)
    sh.SetElementSize(g.sh.shape[1])
    colour = dc_rgb(g).astype(np.float32)
    values, index = np.unique(colour, axis=0, return_inverse=True)  # indexed: splats share colours
    display = UsdGeom.PrimvarsAPI(prim.GetPrim()).CreatePrimvar(
        "displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.vertex)
    display.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(values)))
    display.SetIndices(Vt.IntArray.FromNumpy(np.ascontiguousarray(index.reshape(-1), dtype=np.int32)))
    prim.CreateProjectionModeHintAttr(UsdVol.Tokens.perspective)
    prim.CreateSortingModeHintAttr(UsdVol.Tokens.cameraDistance)
    Usd.ColorSpaceAPI.Apply(prim.GetPrim()).CreateColorSpaceNameAttr(GAUSSIAN_COLOR_SPACE)
    reach = 3.0 * scales.max(axis=1, keepdims=True)  # 3 sigma around each centre
    lo, hi = (pos - reach).min(axis=0), (pos + reach).max(axis=0)
    prim.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]))


def part_name(i: int) -> str:
    return f"part_{i:03d}"


def write_mesh_arrays(stage, path, part: ConvexPart):
    """A collider part's geometry in the crate `stage`: points, triangles, outward face normals (uniform), no
    subdivision (the normals are the surface's)."""
    from pxr import UsdGeom, Vt

    mesh = UsdGeom.Mesh.Define(stage, path)
    points = Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(part.vertices, dtype=np.float32))
    mesh.CreatePointsAttr(points)
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(part.faces)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(part.faces.reshape(-1), dtype=np.int32)))
    mesh.CreateExtentAttr(UsdGeom.PointBased.ComputeExtent(points))
    mesh.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(face_normals(part.vertices, part.faces)))
    mesh.SetNormalsInterpolation(UsdGeom.Tokens.uniform)
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    return mesh


def _write_colliders(stage, path, crate_path, parts: int, material) -> None:
    """The invisible collider group: one Mesh per part referencing its geometry in the crate layer, with
    the physics schemas (convex hull approximation); `material` bound to the group for physics."""
    from pxr import UsdGeom, UsdPhysics, UsdShade

    group = UsdGeom.Xform.Define(stage, path)
    group.CreatePurposeAttr(UsdGeom.Tokens.guide)
    group.CreateVisibilityAttr(UsdGeom.Tokens.invisible)
    UsdShade.MaterialBindingAPI.Apply(group.GetPrim()).Bind(
        material, UsdShade.Tokens.weakerThanDescendants, "physics")  # the purpose PhysX reads
    for i in range(parts):
        mesh = UsdGeom.Mesh.Define(stage, path.AppendChild(part_name(i)))
        mesh.GetPrim().GetReferences().AddReference(f"./{USD_GEOMETRY}", crate_path.AppendChild(part_name(i)))
        UsdPhysics.CollisionAPI.Apply(mesh.GetPrim())
        UsdPhysics.MeshCollisionAPI.Apply(mesh.GetPrim()).CreateApproximationAttr(UsdPhysics.Tokens.convexHull)


def physics_material(stage, path: str):
    """The scene's one physics material: MuJoCo's sliding friction (static and dynamic alike), no bounce."""
    from pxr import UsdPhysics, UsdShade

    material = UsdShade.Material.Define(stage, path)
    api = UsdPhysics.MaterialAPI.Apply(material.GetPrim())
    api.CreateStaticFrictionAttr(FRICTION)
    api.CreateDynamicFrictionAttr(FRICTION)
    api.CreateRestitutionAttr(RESTITUTION)
    return material


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """[F, 3] float32 unit normals of triangles [F, 3] over vertices [V, 3], by the right-hand rule."""
    v = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    return np.ascontiguousarray(n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300), dtype=np.float32)


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
    per_degree = math.pi / 180.0  # USD's angular drive: torque per degree (and per degree per second)
    drive.CreateStiffnessAttr(DOOR_HOLD_STIFFNESS_NM_PER_RAD * per_degree)
    drive.CreateDampingAttr(DOOR_HOLD_DAMPING_NMS_PER_RAD * per_degree)
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

