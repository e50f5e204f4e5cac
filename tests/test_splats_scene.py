"""A scene's Gaussians: every object sampled and tagged, trained PLYs brought to world and assigned ids."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from sagebench.render.gaussians import Gaussians, logit
from sagebench.scene.loader import load_scene
from sagebench.settings.build_scene import SplatConfig
from sagebench.splats.ply import write_ply
from sagebench.splats.scene import quat_multiply, room_views, sampled_gaussians, scene_gaussians, trained_gaussians


@pytest.fixture(scope="module")
def demo(demo_scene_dir):
    return load_scene(demo_scene_dir)


def test_demo_scene_gaussians_cover_every_object_with_its_id(demo):
    g, report = scene_gaussians(demo, seed=0)
    assert report is None
    assert 150_000 < g.count < 400_000
    ids = {o.instance_id for o in demo.spec.objects}
    assert set(np.unique(g.instance_id).tolist()) == ids
    for obj in demo.spec.objects:  # every Gaussian lies on (within the bounds of) its own object's mesh
        lo, hi = demo.meshes[obj.instance_id].bounds
        pts = g.means[g.instance_id == obj.instance_id]
        assert (pts >= lo - 1e-4).all() and (pts <= hi + 1e-4).all(), obj.category
    # unseen structure faces are skipped: nothing under the floor slabs or above the ceilings
    floors = np.isin(g.instance_id, [o.instance_id for o in demo.spec.objects if o.kind == "floor"])
    assert (g.means[floors, 2] > -1e-4).all()


def test_same_seed_same_bytes_other_seed_differs(demo, tmp_path):
    cfg = SplatConfig(object_density=200, structure_density=50)
    write_ply(tmp_path / "a.ply", sampled_gaussians(demo, cfg, seed=3))
    write_ply(tmp_path / "b.ply", sampled_gaussians(demo, cfg, seed=3))
    write_ply(tmp_path / "c.ply", sampled_gaussians(demo, cfg, seed=4))
    assert (tmp_path / "a.ply").read_bytes() == (tmp_path / "b.ply").read_bytes()
    assert (tmp_path / "a.ply").read_bytes() != (tmp_path / "c.ply").read_bytes()


def test_trained_gaussians_are_turned_to_world_and_get_nearest_surface_ids(tmp_path):
    """A Y-up scene in centimetres with a 100 cm box: trained Gaussians near it get its id, far ones 0."""
    scene_dir = tmp_path / "scene"
    (scene_dir / "meshes").mkdir(parents=True)
    box = trimesh.creation.box(extents=(100, 100, 100))
    box.apply_translation((0, 50, 0))  # standing on the Y-up floor
    (scene_dir / "meshes" / "box.ply").write_bytes(box.export(file_type="ply"))
    (scene_dir / "scene.json").write_text(json.dumps({
        "scene_id": "t", "units": "cm", "up_axis": "Y",
        "objects": [{"instance_id": 4, "category": "box", "mesh": "meshes/box.ply"}],
    }))
    # file coordinates (cm, Y up): on the top face, 1 cm off the +X face, and 3 m away
    means = np.array([[0, 100, 0], [51, 50, 10], [300, 50, 0]], np.float32)
    rot_x = np.array([np.cos(0.3), np.sin(0.3), 0, 0])  # a rotation about the file's X axis
    trained = Gaussians(means, np.tile(rot_x, (3, 1)).astype(np.float32), np.log(np.full((3, 3), 2.0, np.float32)),
                        np.full(3, logit(0.5), np.float32), np.zeros((3, 4, 3), np.float32), np.zeros(3, np.int32))
    write_ply(scene_dir / "gaussians.ply", trained)
    scene = load_scene(scene_dir)
    g, _ = scene_gaussians(scene, SplatConfig(assign_tolerance=0.05), trained=trained_gaussians(scene))
    # metres, Z up: file (x, y, z) -> world (x, -z, y) / 100
    assert np.allclose(g.means, [[0, 0, 1.0], [0.51, -0.1, 0.5], [3.0, 0, 0.5]], atol=1e-6)
    assert g.instance_id.tolist() == [4, 4, 0]
    assert np.allclose(np.exp(g.log_scales), 0.02, rtol=1e-5)
    frame_q = np.array([np.cos(np.pi / 4), np.sin(np.pi / 4), 0, 0])  # +90 deg about X
    assert np.allclose(g.quats_wxyz[0], quat_multiply(frame_q, rot_x), atol=1e-6)
    assert g.sh.shape == (3, 1, 3)  # view-dependent bands dropped when the frame turns


def test_room_views_stand_inside_rooms_at_camera_height(demo):
    import shapely
    from shapely.geometry import Polygon

    area = shapely.unary_union([Polygon(r.polygon) for r in demo.spec.rooms])
    views = list(room_views(demo, 12, seed=1, width=64))
    assert len(views) == 12
    for cam in views:
        x, y, z = cam.position
        assert area.contains(shapely.Point(x, y)) and z == pytest.approx(1.2)
        assert (cam.width, cam.height) == (64, 48)


def test_pruning_through_the_config_reports_psnr(demo):
    cfg = SplatConfig(object_density=200, structure_density=50, prune=0.5, prune_views=4, prune_width=64)
    g, report = scene_gaussians(demo, cfg, seed=0)
    full = sampled_gaussians(demo, cfg, seed=0)
    assert report.count_before == full.count and g.count == report.count_after == full.count - round(0.5 * full.count)
    assert 10.0 < report.psnr_db
