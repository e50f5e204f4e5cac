"""Episode sampling: reachable, in-range, distinct, deterministic trajectories; stand points face each other."""

import numpy as np
import pytest

from sagebench.astar.grid_astar import astar
from sagebench.astar.sampling import GridMap, TargetSpec, sample_trajectories
from sagebench.astar.shortcut import polyline_length
from sagebench.settings.gen_trajectories import SamplingConfig

RES = 0.05


def _square(x0, y0, x1, y1):
    return (np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64),)


def _two_rooms() -> tuple[GridMap, list[TargetSpec]]:
    """8 m x 4 m, a wall at x = 4 m with a 1 m gap at y 1.5-2.5 m; a box in each room; both rooms."""
    nav = np.ones((80, 160), dtype=np.uint8)
    nav[[0, -1], :] = 0
    nav[:, [0, -1]] = 0
    nav[:, 78:82] = 0
    nav[30:50, 78:82] = 1
    for x0, y0 in ((1.5, 2.5), (6.0, 1.0)):  # 0.6 m boxes, inflated by 0.2 m
        nav[int((y0 - 0.2) / RES):int((y0 + 0.8) / RES), int((x0 - 0.2) / RES):int((x0 + 0.8) / RES)] = 0
    grid = GridMap(nav, RES, (0.0, 0.0), 0.5)
    targets = [
        TargetSpec("object:1", "object", 1, "a", _square(1.5, 2.5, 2.1, 3.1)),
        TargetSpec("object:2", "object", 2, "b", _square(6.0, 1.0, 6.6, 1.6)),
        TargetSpec("room:a", "room", None, "a", _square(0, 0, 3.95, 4)),
        TargetSpec("room:b", "room", None, "b", _square(4.05, 0, 8, 4)),
    ]
    return grid, targets


def test_every_trajectory_is_navigable_in_range_and_starts_and_ends_where_the_path_does():
    grid, targets = _two_rooms()
    cfg = SamplingConfig(per_scene=50, min_geodesic_m=0.1, max_geodesic_m=20.0)
    result = sample_trajectories(grid, targets, "two_rooms", cfg)
    assert result.pairs_tried == 12 == len(result.trajectories) + sum(result.rejected.values())
    # an object right beside its room's centre is too short a trip; an object's own room is no goal from it
    assert len(result.trajectories) >= 9
    for t in result.trajectories:
        assert grid.navigable[t.cells[:, 0], t.cells[:, 1]].all()
        assert 0.1 <= t.path_length_m <= 20.0
        assert t.path_length_m <= t.grid_length_m + 1e-9
        assert t.path_length_m == pytest.approx(polyline_length(t.waypoints))
        assert astar(grid.navigable, tuple(t.cells[0]), tuple(t.cells[-1]), RES).cost == pytest.approx(t.grid_length_m)
        np.testing.assert_allclose(t.waypoints[[0, -1], 0], (t.cells[[0, -1], 1] + 0.5) * RES)
        np.testing.assert_allclose(t.waypoints[[0, -1], 1], (t.cells[[0, -1], 0] + 0.5) * RES)
        assert (t.waypoints[:, 2] == 0.5).all()
    assert len({t.trajectory_id for t in result.trajectories}) == len(result.trajectories)


def test_goal_stand_point_is_beside_the_footprint_on_the_side_facing_the_start():
    grid, targets = _two_rooms()
    result = sample_trajectories(grid, targets, "two_rooms", SamplingConfig(per_scene=50, min_geodesic_m=0.5))
    to_box2 = next(t for t in result.trajectories if t.start.key == "room:a" and t.goal.key == "object:2")
    gx, gy = to_box2.waypoints[-1, :2]
    assert gx < 6.0 and 1.0 <= gy <= 1.7  # west side of box 2, towards room a (north-west corner allowed)
    assert 6.0 - gx <= 0.225 + 0.1  # within approach_tolerance_m of the nearest navigable cell
    from_box2 = next(t for t in result.trajectories if t.start.key == "object:2" and t.goal.key == "room:a")
    sx, sy = from_box2.waypoints[0, :2]
    assert sx < 6.0  # the start faces room a's centre (2.0, 2.0), west of the box


def test_room_stand_point_is_near_the_room_centre():
    grid, targets = _two_rooms()
    result = sample_trajectories(grid, targets, "two_rooms", SamplingConfig(per_scene=50, min_geodesic_m=0.5))
    t = next(t for t in result.trajectories if t.goal.key == "room:b")
    assert np.hypot(*(t.waypoints[-1, :2] - (6.025, 2.0))) < 0.15


def test_same_seed_same_trajectories_other_seed_other_order():
    grid, targets = _two_rooms()
    run = lambda seed: [t.trajectory_id for t in sample_trajectories(  # noqa: E731
        grid, targets, "two_rooms", SamplingConfig(per_scene=5, seed=seed, min_geodesic_m=0.5)).trajectories]
    assert run(1) == run(1)
    assert run(1) != run(2)


def test_range_filter_and_short_result_report_why():
    grid, targets = _two_rooms()
    result = sample_trajectories(grid, targets, "two_rooms", SamplingConfig(per_scene=50, min_geodesic_m=5.0))
    assert len(result.trajectories) < 12 and result.pairs_tried == 12
    assert result.rejected["shorter than min_geodesic_m"] == 12 - len(result.trajectories)
    assert all(t.path_length_m >= 5.0 for t in result.trajectories)


def test_target_without_a_nearby_navigable_cell_is_reported_and_skipped():
    grid, targets = _two_rooms()
    nav = grid.navigable.copy()
    nav[50:80, 0:40] = 0  # bury box 1 in a blocked corner far beyond approach_max_m
    grid = GridMap(nav, RES, grid.origin, grid.floor_z)
    buried = TargetSpec("object:9", "object", 9, "a", _square(0.2, 3.5, 0.4, 3.7))
    result = sample_trajectories(grid, [*targets, buried], "two_rooms", SamplingConfig(per_scene=50))
    assert result.unreachable_targets == ["object:9"]
    assert all("object:9" not in (t.start.key, t.goal.key) for t in result.trajectories)


def test_demo_scene_gives_the_default_200_trajectories_on_navigable_cells(demo_built_run):
    from sagebench.episodes.targets import scene_targets
    from sagebench.settings.gen_trajectories import GenTrajectoriesConfig
    from sagebench.stages.gen_trajectories import read_scene_inputs

    spec, smap, grid, _ = read_scene_inputs(demo_built_run / "scenes" / "demo_apartment_0")
    targets, names = scene_targets(spec, smap)
    result = sample_trajectories(grid, targets, spec.scene_id, GenTrajectoriesConfig())
    assert len(result.trajectories) == 200
    kinds = {(t.start.kind, t.goal.kind) for t in result.trajectories}
    assert kinds == {("object", "object"), ("object", "room"), ("room", "object"), ("room", "room")}
    for t in result.trajectories:
        assert grid.navigable[t.cells[:, 0], t.cells[:, 1]].all()
        assert 2.0 <= t.path_length_m <= 20.0


def test_no_room_goal_starts_inside_its_goal_room():
    grid, targets = _two_rooms()
    result = sample_trajectories(grid, targets, "two_rooms", SamplingConfig(per_scene=50, min_geodesic_m=0.1))
    pairs = {(t.start.key, t.goal.key) for t in result.trajectories}
    assert ("object:1", "room:a") not in pairs and ("object:2", "room:b") not in pairs
    assert ("object:1", "room:b") in pairs
    # box 2 -> room b is even shorter than min_geodesic_m (box 2 stands by room b's centre)
    assert result.rejected == {"shorter than min_geodesic_m": 2, "starts inside the goal room": 1}


def test_start_and_goal_rooms_come_from_the_positions_not_the_annotation():
    grid, targets = _two_rooms()
    # box 1 annotated in room b although it stands in room a: its stand points are in room a
    targets[0] = TargetSpec("object:1", "object", 1, "b", targets[0].outlines)
    result = sample_trajectories(grid, targets, "two_rooms", SamplingConfig(per_scene=50, min_geodesic_m=0.1))
    to_box1 = next(t for t in result.trajectories if t.goal.key == "object:1")
    from_box1 = next(t for t in result.trajectories if t.start.key == "object:1")
    assert to_box1.goal_room == "a" and from_box1.start_room == "a"
    for t in result.trajectories:
        for (x, y), room in ((t.waypoints[0, :2], t.start_room), (t.waypoints[-1, :2], t.goal_room)):
            assert room == ("a" if x <= 3.95 else "b" if x >= 4.05 else None)
