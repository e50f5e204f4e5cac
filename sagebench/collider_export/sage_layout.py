"""A scene in SAGE-3D's per-scene USDA form, so SAGE's own evaluator opens sagebench scenes in Isaac Sim 5.

SAGE-3D makes <scene_id>.usda from its Data/template.usda (Code/benchmark/scene_data/sage3d_usda_builder.py
swaps two asset paths and the authoring layer's name) and its evaluator opens that file, looks for the
collision prim at /World/scene_collision and makes it visible to render depth. The form, as written here:

    layer       defaultPrim World, metersPerUnit 1, upAxis Z, timeCodesPerSecond 24; customLayerData:
                renderSettings (the template's) and omni_layer.authoring_layer "./<scene_id>.usda"
    /World                   Xform
        gauss                over, references @<NuRec USDZ>[gauss.usda]@ (splats.nurec: the volume lands at
                             /World/gauss/gauss); xformOp translate, rotateXYZ, scale
        scene_collision      def, payload @./<scene_id>_collision.usd@, visibility invisible; xformOp translate,
                             orient, scale

sagebench's Gaussians and colliders are both in the world frame, so its ops are identities where the template's
undo InteriorGS's frames (rotateXYZ (-90, 0, 0) on the Gaussians, a half turn about Z on the collision mesh).

The collision layer (<scene_id>_collision.usd, crate, self-contained like SAGE's Collision/<id>/<id>_collision.usd):
defaultPrim /Collision (Xform) holding the physics material and one Xform per object at its pose
(<category>_<instance_id>, semantics as in scene.usda) with its convex parts as Meshes (points, triangles,
normals) with CollisionAPI + MeshCollisionAPI convexHull. Static, as SAGE's collision meshes are: doors stand
at their state's angle; scene.usda keeps the rigid bodies and hinges.
"""

from __future__ import annotations

import tempfile
from collections.abc import Sequence
from pathlib import Path

from sagebench.collider_export.usd_writer import (
    StageObject, gf_matrix, part_name, physics_material, prim_name, stage_metadata, write_mesh_arrays,
    write_semantics,
)

TEMPLATE_RENDER_SETTINGS = {  # Data/template.usda's customLayerData renderSettings
    "rtx:directLighting:sampledLighting:samplesPerPixel": 8,
    "rtx:externalFrameCounter": 120,
    "rtx:material:enableRefraction": False,
    "rtx:matteObject:visibility:secondaryRays": True,
    "rtx:post:tonemap:op": 2,
}
COLLISION_ROOT = "/Collision"


def sage_root_name(scene_id: str) -> str:
    return f"{scene_id}.usda"


def sage_collision_name(scene_id: str) -> str:
    return f"{scene_id}_collision.usd"


def sage_files(scene_id: str, objects: Sequence[StageObject], nurec: str) -> dict[str, bytes]:
    """The two files by name: the root (sage_root_name) referencing the NuRec USDZ at relative path `nurec`, and
    the collision layer (sage_collision_name) with the objects' colliders. Same inputs, same bytes."""
    with tempfile.TemporaryDirectory(prefix="sagebench-sage-") as tmp:
        _collision_layer(Path(tmp) / sage_collision_name(scene_id), objects)
        _root_layer(Path(tmp) / sage_root_name(scene_id), scene_id, nurec)
        return {p.name: p.read_bytes() for p in sorted(Path(tmp).iterdir())}


def _root_layer(path: Path, scene_id: str, nurec: str) -> None:
    from pxr import Gf, Usd, UsdGeom, UsdUtils

    from sagebench.splats.nurec import GAUSS_LAYER

    stage = Usd.Stage.CreateNew(str(path))
    stage_metadata(stage)
    stage.SetTimeCodesPerSecond(24.0)
    stage.SetMetadataByDictKey("customLayerData", "renderSettings", TEMPLATE_RENDER_SETTINGS)
    stage.SetMetadataByDictKey("customLayerData", "omni_layer",
                               {"authoring_layer": f"./{path.name}", "locked": {}, "muteness": {}})
    world = UsdGeom.Xform.Define(stage, "/World")
    world.CreateVisibilityAttr(UsdGeom.Tokens.inherited)
    stage.SetDefaultPrim(world.GetPrim())
    quiet = UsdUtils.CoalescingDiagnosticDelegate()  # the files it names are written beside it afterwards
    gauss = stage.OverridePrim("/World/gauss")
    gauss.GetReferences().AddReference(f"{nurec}[{GAUSS_LAYER}]")
    ops = UsdGeom.Xformable(gauss)
    UsdGeom.Imageable(gauss).CreateVisibilityAttr(UsdGeom.Tokens.inherited)
    ops.AddTranslateOp().Set(Gf.Vec3d(0.0, 0.0, 0.0))
    ops.AddRotateXYZOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Vec3d(0.0, 0.0, 0.0))
    ops.AddScaleOp(UsdGeom.XformOp.PrecisionDouble).Set(Gf.Vec3d(1.0, 1.0, 1.0))
    collision = stage.DefinePrim("/World/scene_collision")
    collision.GetPayloads().AddPayload(f"./{sage_collision_name(scene_id)}")
    UsdGeom.Imageable(collision).CreateVisibilityAttr(UsdGeom.Tokens.invisible)
    ops = UsdGeom.Xformable(collision)
    ops.AddTranslateOp().Set(Gf.Vec3d(0.0, 0.0, 0.0))
    ops.AddOrientOp().Set(Gf.Quatf(1.0))
    ops.AddScaleOp().Set(Gf.Vec3f(1.0, 1.0, 1.0))
    del quiet
    stage.GetRootLayer().Save()


def _collision_layer(path: Path, objects: Sequence[StageObject]) -> None:
    from pxr import Sdf, Usd, UsdGeom, UsdPhysics, UsdShade

    stage = Usd.Stage.CreateNew(str(path))
    stage_metadata(stage)
    root = UsdGeom.Xform.Define(stage, COLLISION_ROOT)
    stage.SetDefaultPrim(root.GetPrim())
    material = physics_material(stage, f"{COLLISION_ROOT}/PhysicsMaterial")
    for obj in objects:
        body = UsdGeom.Xform.Define(stage, Sdf.Path(COLLISION_ROOT).AppendChild(prim_name(obj)))
        body.AddTransformOp().Set(gf_matrix(obj.matrix))
        write_semantics(body.GetPrim(), obj)
        UsdShade.MaterialBindingAPI.Apply(body.GetPrim()).Bind(
            material, UsdShade.Tokens.weakerThanDescendants, "physics")
        for i, part in enumerate(obj.parts):
            mesh = write_mesh_arrays(stage, body.GetPath().AppendChild(part_name(i)), part)
            UsdPhysics.CollisionAPI.Apply(mesh.GetPrim())
            UsdPhysics.MeshCollisionAPI.Apply(mesh.GetPrim()).CreateApproximationAttr(UsdPhysics.Tokens.convexHull)
    stage.GetRootLayer().Save()
