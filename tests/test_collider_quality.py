"""The collider quality measure on shapes whose answers are known by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from sagebench.collider_export.convex import hull_part
from sagebench.collider_export.quality import (
    BandReach, _distances, _inside, band_errors, band_in_mesh_frame, band_polygons, inside_reference, measure,
    measure_objects, measure_placed, part_planes,
)
from sagebench.settings.shared import AgentConfig

# an L: [0,2]x[0,1] plus [0,1]x[1,2], 1 m tall; its hull adds the triangle (1,1) (2,1) (1,2), 0.5 m^2 x 1 m
BAND = AgentConfig().band  # the default agent's over a floor at z = 0, as z in the meshes' frame (m)
L_SHAPE = trimesh.creation.extrude_triangulation(
    np.array([(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)], float), np.array([(0, 1, 2), (0, 2, 3), (0, 3, 5), (3, 4, 5)]), 1.0)
LEG_A = trimesh.creation.box(bounds=[[0, 0, 0], [2, 1, 1]])
LEG_B = trimesh.creation.box(bounds=[[0, 1, 0], [1, 2, 1]])


def test_a_box_is_its_own_hull():
    box = trimesh.creation.box((1.0, 2.0, 0.8)).apply_translation((0.3, 0.1, 0.4))
    q = measure(box.vertices, box.faces, [hull_part(box.vertices)], band=BAND)
    assert q.to_source_max_cm < 1e-9 and q.from_source_max_cm == 0.0
    assert q.outside_volume_l == 0.0 and q.band_over_cm == 0.0 and q.band_under_cm == 0.0


def test_the_hull_of_an_l_bridges_its_notch():
    q = measure(L_SHAPE.vertices, L_SHAPE.faces, [hull_part(L_SHAPE.vertices)], band=BAND)
    # the farthest hull point from the L is the middle of the bridging face, (1.5, 1.5): 0.5 m from x = 1 and y = 1
    assert 45.0 <= q.to_source_max_cm <= 50.0 + 1e-9
    assert q.band_over_cm == pytest.approx(50.0, abs=1.0) and q.band_under_cm == 0.0
    assert q.from_source_max_cm == 0.0
    # the notch is 500 l; voxels the L's surface touches (2 cm thick, 2.5 m^2 facing the notch) count as the L's
    assert 500.0 - 2.5 * 0.02 * 1000 <= q.outside_volume_l <= 500.0


def test_two_touching_boxes_are_the_l_exactly():
    q = measure(L_SHAPE.vertices, L_SHAPE.faces, [hull_part(LEG_A.vertices), hull_part(LEG_B.vertices)], band=BAND)
    # the face the two boxes share is inside the collider, not its surface
    assert q.to_source_max_cm < 1e-9 and q.from_source_max_cm == 0.0
    assert q.outside_volume_l == 0.0 and q.band_over_cm == 0.0 and q.band_under_cm == 0.0


def test_a_missing_leg_is_under_coverage():
    q = measure(L_SHAPE.vertices, L_SHAPE.faces, [hull_part(LEG_A.vertices)], band=BAND)
    assert 90.0 <= q.from_source_max_cm <= 100.0 + 1e-9  # the far end of leg B, y = 2, is 1 m from leg A
    assert q.band_under_cm == pytest.approx(100.0, abs=1.0) and q.band_over_cm == 0.0
    # leg A's face y = 1 under where leg B should be lies inside the L: 0.5 m from its surface at (0.5, 1, 0.5)
    assert 45.0 <= q.to_source_max_cm <= 50.0 + 1e-9 and q.outside_volume_l == 0.0


def test_overlapping_parts_count_their_shared_volume_once():
    hull = hull_part(L_SHAPE.vertices)
    alone = measure(L_SHAPE.vertices, L_SHAPE.faces, [hull], band=BAND).outside_volume_l
    assert measure(L_SHAPE.vertices, L_SHAPE.faces, [hull, hull], band=BAND).outside_volume_l == alone
    # the hull's 500 l over the notch lies inside a box filling the notch: outside the L is that box's 1000 l, less
    # the voxels the L's two faces on the notch (2 m^2, one 2 cm voxel thick) claim
    notch = hull_part(trimesh.creation.box(bounds=[[1, 1, 0], [2, 2, 1]]).vertices)
    both = measure(L_SHAPE.vertices, L_SHAPE.faces, [hull, notch], band=BAND).outside_volume_l
    assert 1000.0 - 2.0 * 0.02 * 1000 <= both <= 1000.0


def test_only_the_agent_band_counts_for_navigation():
    lamp = L_SHAPE.copy().apply_translation((0, 0, 1.3))  # hangs above 1.2 m: its bad hull blocks nobody
    q = measure(lamp.vertices, lamp.faces, [hull_part(lamp.vertices)], band=BAND)
    assert q.band_over_cm == 0.0 and q.band_under_cm == 0.0 and q.to_source_max_cm > 45.0
    # 1.15 m up, only its bottom 5 cm is in the band, and there the hull still bridges the notch
    low = L_SHAPE.copy().apply_translation((0, 0, 1.15))
    low_q = measure(low.vertices, low.faces, [hull_part(low.vertices)], band=BAND)
    assert low_q.band_over_cm == pytest.approx(50.0, abs=1.0)


def test_band_in_mesh_frame_and_placed_measures_agree():
    yaw = trimesh.transformations.rotation_matrix(0.7, (0, 0, 1))
    yaw[:3, 3] = (1.0, -2.0, 0.5)
    raised = (0.1 + BAND[0], 0.1 + BAND[1])  # a floor at 0.1 m
    assert band_in_mesh_frame(yaw, raised) == pytest.approx((0.1 + 0.05 - 0.5, 0.1 + 1.2 - 0.5))
    tilt = trimesh.transformations.rotation_matrix(math.pi / 2, (1, 0, 0))
    assert band_in_mesh_frame(tilt, BAND) is None
    parts = [hull_part(L_SHAPE.vertices)]
    placed = measure_placed(L_SHAPE.vertices, L_SHAPE.faces, parts, yaw, raised)
    world = measure(trimesh.transform_points(L_SHAPE.vertices, yaw), L_SHAPE.faces,
                    [hull_part(trimesh.transform_points(L_SHAPE.vertices, yaw))], band=(0.15, 1.3))
    assert placed.to_source_max_cm == pytest.approx(world.to_source_max_cm, abs=0.5)
    assert placed.band_over_cm == pytest.approx(world.band_over_cm, abs=1.5)
    # tilted onto its side: measured in world coordinates, where the L is 2 m tall and 1 m deep
    on_side = measure_placed(L_SHAPE.vertices, L_SHAPE.faces, parts, tilt, BAND)
    assert on_side.band_over_cm == pytest.approx(0.0, abs=1.0)  # its shadow in the band is a full rectangle


def test_inside_agrees_with_every_point_against_every_plane():
    rng = np.random.default_rng(3)
    sphere = trimesh.creation.icosphere(subdivisions=3)  # 1280 planes, like a detailed hull part
    planes = part_planes(hull_part(sphere.vertices))
    points = rng.uniform(-1.2, 1.2, size=(4000, 3))
    margin = (points @ planes[:, :3].T - planes[:, 3]).max(axis=1)
    clear = np.abs(margin - 1e-9) > 1e-12  # the two sum in different orders: leave out points on a plane
    assert np.array_equal(_inside(points, planes)[clear], inside_reference(points, planes)[clear])
    assert 0.2 < _inside(points, planes).mean() < 0.4  # both sides are exercised (the ball is 0.24 of the cube)
    beyond_each = planes[:, :3] * (planes[:, 3:] + 1e-3)  # just past each plane, on its normal: outside it alone
    assert not _inside(beyond_each, planes).any() and _inside(0.99 * beyond_each, planes).all()


def test_distances_agree_with_trimesh_closest_point():
    rng = np.random.default_rng(4)
    mesh = trimesh.util.concatenate([L_SHAPE, trimesh.creation.icosphere(2).apply_translation((3, 0, 0.5))])
    points = np.concatenate([rng.uniform(-1, 4, size=(500, 3)), mesh.vertices[:20], mesh.triangles_center[:20]])
    _, expected, _ = trimesh.proximity.closest_point(mesh, points)
    np.testing.assert_allclose(_distances(mesh, points), expected, rtol=0, atol=1e-12)


def test_measure_objects_measures_each_mesh_and_band_once_on_any_number_of_workers():
    meshes = {"l": (L_SHAPE.vertices, L_SHAPE.faces), "leg": (LEG_A.vertices, LEG_A.faces)}
    parts = {"l": [hull_part(L_SHAPE.vertices)], "leg": [hull_part(LEG_A.vertices)]}
    shifted = np.eye(4)
    shifted[:3, 3] = (5.0, 0.0, 0.0)  # the same band height: the same measurement
    placed = [(1, "l", np.eye(4)), (2, "leg", np.eye(4)), (3, "l", shifted)]
    one = measure_objects(placed, meshes, parts, BAND, workers=1)
    assert one == measure_objects(placed, meshes, parts, BAND, workers=2)
    assert one[1] == one[3] == measure(L_SHAPE.vertices, L_SHAPE.faces, parts["l"], band=BAND)
    assert one[2].band_over_cm == 0.0 and one[1].band_over_cm == pytest.approx(50.0, abs=1.0)


def test_band_reach_agrees_with_the_band_measure_of_one_part():
    """BandReach (the merge's test) is band_errors' `over` for one part, up to the one cell its raster's
    origin may shift: the L's hull reaches 0.5 m past it (the middle of the edge bridging the notch); on
    the real fixtures, their pieces' hulls, coarse voxel parts and whole hulls."""
    from sagebench.collider_export.convex import split_convex
    from sagebench.collider_export.voxel import voxel_parts
    from tests.test_collider_decompose import _fixture_meshes

    hull = hull_part(L_SHAPE.vertices)
    assert BandReach(L_SHAPE, hull.vertices, (0.05, 0.95))(hull) == pytest.approx(0.5, abs=0.01)
    pairs = []
    for m in _fixture_meshes().values():
        split = split_convex(m.vertices, m.faces)
        parts = [*split.parts, *(hull_part(v) for v, _ in split.concave), hull_part(m.vertices),
                 *voxel_parts(m.vertices, m.faces, pitch=0.05, max_parts=8)]
        reach = BandReach(m, np.concatenate([p.vertices for p in parts]), BAND)
        pairs += [(reach(p), band_errors(m, [p], BAND, 0.01)[0]) for p in parts
                  if band_polygons(p.vertices[p.faces], *BAND)]
    fast, reference = np.array(pairs).T
    assert len(pairs) > 100 and np.abs(fast - reference).max() <= 0.01 + 1e-9
    assert np.mean(fast == reference) > 0.9
