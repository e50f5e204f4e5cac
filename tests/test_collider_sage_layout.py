"""SAGE-3D's per-scene USDA: what its template (Data/template.usda), its builder (sage3d_usda_builder.py) and its
evaluator (simple_env.py) rely on, opened with usd-core: the NuRec reference, the ops, the collision payload."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
from pxr import Sdf, Usd, UsdGeom, UsdPhysics, UsdSemantics, UsdVol

from sagebench.collider_export.sage_layout import sage_collision_name, sage_files, sage_root_name
from sagebench.splats.nurec import nurec_usdz
from tests.test_usd_writer import BACKGROUND, OBJECTS


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    """A scene directory as export-usd --gaussians nurec --layout sage leaves it: gaussians.usdz, sage/."""
    root = tmp_path_factory.mktemp("sage") / "tiny"
    (root / "sage").mkdir(parents=True)
    (root / "gaussians.usdz").write_bytes(nurec_usdz(BACKGROUND))
    for name, data in sage_files("tiny", OBJECTS, "../gaussians.usdz").items():
        (root / "sage" / name).write_bytes(data)
    return root


def test_files_are_named_as_sage_finds_them(scene):
    # run_benchmark.find_matching_scene_file looks for <scene_name>.usda; the builder's collision path ends
    # {scene_id}_collision.usd
    assert sorted(p.name for p in (scene / "sage").iterdir()) == ["tiny.usda", "tiny_collision.usd"]
    assert (sage_root_name("tiny"), sage_collision_name("tiny")) == ("tiny.usda", "tiny_collision.usd")


def test_root_layer_in_template_form(scene):
    layer = Sdf.Layer.FindOrOpen(str(scene / "sage" / "tiny.usda"))
    assert layer.GetFileFormat().formatId == "usda"
    assert (layer.defaultPrim, layer.timeCodesPerSecond) == ("World", 24.0)
    assert layer.pseudoRoot.GetInfo("upAxis") == "Z" and layer.pseudoRoot.GetInfo("metersPerUnit") == 1.0
    data = layer.customLayerData
    assert data["omni_layer"]["authoring_layer"] == "./tiny.usda"  # what the builder makes sure of
    assert data["renderSettings"]["rtx:post:tonemap:op"] == 2
    gauss = layer.GetPrimAtPath("/World/gauss")
    assert gauss.specifier == Sdf.SpecifierOver
    (ref,) = gauss.referenceList.prependedItems  # the template's @usdz_root[gauss.usda]@, a package path
    assert (ref.assetPath, ref.primPath) == ("../gaussians.usdz[gauss.usda]", Sdf.Path())
    assert list(gauss.attributes["xformOpOrder"].default) == ["xformOp:translate", "xformOp:rotateXYZ", "xformOp:scale"]
    assert gauss.attributes["xformOp:rotateXYZ"].typeName == Sdf.ValueTypeNames.Double3
    collision = layer.GetPrimAtPath("/World/scene_collision")
    assert (collision.specifier, collision.typeName) == (Sdf.SpecifierDef, "")  # typeless def, as the template
    (payload,) = collision.payloadList.prependedItems  # the template's @collision_root@
    assert payload.assetPath == "./tiny_collision.usd"
    assert collision.attributes["visibility"].default == "invisible"
    assert list(collision.attributes["xformOpOrder"].default) == ["xformOp:translate", "xformOp:orient", "xformOp:scale"]
    assert collision.attributes["xformOp:orient"].typeName == Sdf.ValueTypeNames.Quatf


def test_composed_stage_has_the_nurec_volume_and_every_collider_in_the_world_frame(scene):
    stage = Usd.Stage.Open(str(scene / "sage" / "tiny.usda"))
    volume = stage.GetPrimAtPath("/World/gauss/gauss")
    assert volume.IsA(UsdVol.Volume) and volume.GetAttribute("omni:nurec:isNuRecVolume").Get()
    cache = UsdGeom.XformCache()
    assert np.allclose(np.array(cache.GetLocalToWorldTransform(volume)), np.eye(4))  # Gaussians in world metres
    root = stage.GetPrimAtPath("/World/scene_collision")
    assert root.GetTypeName() == "Xform" and UsdGeom.Imageable(root).ComputeVisibility() == "invisible"
    for obj in OBJECTS:
        body = root.GetChild(f"{obj.category}_{obj.instance_id}")
        assert UsdSemantics.LabelsAPI(body, "class").GetLabelsAttr().Get() == [obj.category]
        assert UsdSemantics.LabelsAPI(body, "instance").GetLabelsAttr().Get() == [str(obj.instance_id)]
        meshes = [p for p in body.GetChildren() if p.IsA(UsdGeom.Mesh)]
        assert len(meshes) == len(obj.parts)
        for prim, part in zip(meshes, obj.parts):
            assert prim.HasAPI(UsdPhysics.CollisionAPI)
            assert UsdPhysics.MeshCollisionAPI(prim).GetApproximationAttr().Get() == "convexHull"
            m = np.array(cache.GetLocalToWorldTransform(prim)).T
            pts = np.array(UsdGeom.Mesh(prim).GetPointsAttr().Get(), dtype=np.float64)
            assert np.allclose(pts @ m[:3, :3].T + m[:3, 3], trimesh.transform_points(part.vertices, obj.matrix),
                               atol=1e-5)
            assert not prim.HasAPI(UsdPhysics.RigidBodyAPI)  # static, as SAGE's collision meshes


def test_the_evaluator_makes_the_collision_visible_for_depth(scene):
    """simple_env._make_collision_mesh_visible_for_depth: finds /World/scene_collision, sets it visible; every
    collider mesh then renders (no purpose hides it from a camera)."""
    stage = Usd.Stage.Open(str(scene / "sage" / "tiny.usda"))
    root = stage.GetPrimAtPath("/World/scene_collision")
    UsdGeom.Imageable(root).GetVisibilityAttr().Set(UsdGeom.Tokens.visible)
    meshes = [p for p in Usd.PrimRange(root) if p.IsA(UsdGeom.Mesh)]
    assert len(meshes) == sum(len(o.parts) for o in OBJECTS)
    for prim in meshes:
        assert UsdGeom.Imageable(prim).ComputeVisibility() == "inherited"
        assert UsdGeom.Imageable(prim).ComputePurpose() == "default"


def test_files_are_byte_identical_from_run_to_run():
    assert sage_files("tiny", OBJECTS, "../gaussians.usdz") == sage_files("tiny", OBJECTS, "../gaussians.usdz")


def test_nvidia_asset_validator_cli_exits_0_on_both_files(scene):
    cli = Path(sys.executable).with_name("omni_asset_validate")
    for name in ("tiny.usda", "tiny_collision.usd"):
        run = subprocess.run([str(cli), str(scene / "sage" / name)], capture_output=True, text=True)
        problems = [line for line in (run.stdout + run.stderr).splitlines() if line.startswith(("WARNING", "ERROR"))]
        assert (run.returncode, problems) == (0, []), name
