"""Line of sight on the map: objects behind a wall are not "passed", objects seen through a doorway are."""

from __future__ import annotations

import numpy as np
import pytest
from shapely.geometry import box

from sagebench.instructions.relations import layout, objects_passed, rooms_along
from sagebench.instructions.sight import objects_seen, sight_map

RES = 0.05


def _square(x0, y0, x1, y1):
    return [np.array([(x0, y0), (x1, y0), (x1, y1), (x0, y1)], float)]


@pytest.fixture(scope="module")
def two_rooms():
    """8 x 4 m, a wall at x 3.95..4.05 with a doorway at y 1.5..2.5 that the wall's footprint spans (a hull)."""
    occ = np.zeros((80, 160), np.uint8)
    xs = (np.arange(160) + 0.5) * RES
    ys = (np.arange(80) + 0.5) * RES
    wall_cols = (xs >= 3.95) & (xs <= 4.05)
    door_rows = (ys >= 1.5) & (ys <= 2.5)
    occ[np.ix_(~door_rows, wall_cols)] = 1
    sight = sight_map(occ, RES, (0.0, 0.0), [box(3.95, 0.0, 4.05, 4.0)])
    lay = layout({1: _square(4.2, 0.3, 4.5, 0.6),  # lamp behind the wall, 0.5 m from the path's end
                  2: _square(3.0, 0.3, 3.4, 0.6),  # chair on the path's side
                  3: _square(4.3, 1.8, 4.6, 2.1)})  # plant seen through the doorway
    path = np.array([(1.0, 0.9), (3.8, 0.9), (3.8, 1.9)])
    return lay, path, sight


def test_an_object_behind_a_wall_is_near_the_path_but_not_seen(two_rooms):
    lay, path, sight = two_rooms
    ids = lambda idx: sorted(lay.ids[j] for j in idx)  # noqa: E731
    assert ids(objects_passed(lay, path)) == [1, 2, 3]
    assert ids(objects_seen(lay, path, sight)) == [2, 3]  # the plant through the doorway, not the lamp
    assert ids(objects_seen(lay, path, None)) == [1, 2, 3]


def test_the_doorway_is_what_lets_the_view_through(two_rooms):
    lay, path, sight = two_rooms
    shut = sight_map(np.where(sight.walls | (np.abs((np.arange(160) + 0.5) * RES - 4.0) <= 0.05)[None, :], 1, 0)
                     .astype(np.uint8), RES, (0.0, 0.0), [box(3.95, 0.0, 4.05, 4.0)])
    assert sorted(lay.ids[j] for j in objects_seen(lay, path, shut)) == [2]


def test_a_kitchen_path_of_the_demo_lists_no_study_object(demo_built_run):
    """The issue's example: a path inside the kitchen listed the study's floor lamp behind the wall."""
    from sagebench.astar.sampling import sample_trajectories
    from sagebench.episodes.targets import scene_context, scene_sight, scene_targets
    from sagebench.stages.gen_trajectories import GenTrajectoriesConfig, read_scene_inputs

    spec, smap, grid, occupancy = read_scene_inputs(demo_built_run / "scenes" / "demo_apartment_0")
    ctx = scene_context(spec, smap)
    sight = scene_sight(smap, grid, occupancy)
    targets, _ = scene_targets(spec, smap, ctx)
    room_of = {o.instance_id: o.room_id for o in ctx.objects}
    doors = {o.instance_id for o in ctx.objects if o.category == "door"}  # they stand in the walls, seen from both sides
    lamp = next(i for i, n in ctx.names.items() if n == "the floor lamp in the study")
    kitchen = next(r.id for r in ctx.rooms if r.type == "kitchen")
    lamp_passed = 0
    for t in sample_trajectories(grid, targets, spec.scene_id, GenTrajectoriesConfig(per_scene=200)).trajectories:
        xy = t.waypoints[:, :2]
        if rooms_along(xy, ctx.room_polygons) != [kitchen]:
            continue
        seen = {ctx.layout.ids[j] for j in objects_seen(ctx.layout, xy, sight)}
        assert {room_of[i] for i in seen - doors} <= {kitchen}, [ctx.names.get(i) for i in seen - doors]
        lamp_passed += lamp in {ctx.layout.ids[j] for j in objects_passed(ctx.layout, xy)}
    assert lamp_passed > 0  # within 1 m of some kitchen paths, behind the wall



def test_the_share_of_a_footprint_in_sight_counts_what_no_wall_hides(two_rooms):
    """export-habitat's view point iou: from the left room the chair is all in sight and the lamp behind the wall
    none of it, the two together in the share of their points; through the doorway the plant is in sight."""
    import shapely

    from sagebench.instructions.sight import FOOTPRINT_POINTS, footprint_points

    _, _, sight = two_rooms
    shapes = {"chair": box(3.0, 0.3, 3.4, 0.6), "lamp": box(4.2, 0.3, 4.5, 0.6), "plant": box(4.3, 1.8, 4.6, 2.1)}
    chair, lamp, plant = (footprint_points([shapes[k]], RES, (0.0, 0.0)) for k in ("chair", "lamp", "plant"))
    assert len(chair) == len(lamp) == FOOTPRINT_POINTS and shapely.contains_xy(shapes["lamp"], *lamp.T).all()
    here = np.array([[2.0, 0.45], [3.5, 2.0]])
    assert sight.share_seen(here, chair).tolist() == [1.0, 1.0]
    assert sight.share_seen(here[:1], lamp).tolist() == [0.0]
    assert sight.share_seen(here[:1], np.concatenate([chair, lamp[:16]])).tolist() == [32 / 48]
    assert sight.share_seen(here[1:], plant).tolist() == [1.0]
