"""No-goal coverage and the goal tasks' scores, on hand-made navigable maps (docs/tasks.md)."""

from __future__ import annotations

import numpy as np
import pytest

from sagebench.metrics.coverage import coverage, main_region, swept_cells
from sagebench.metrics.exploration import collision_count, score_exploration
from sagebench.metrics.goal import score_goal
from sagebench.metrics.on_foot import NavigableMap

RES = 0.05
RADIUS = 0.2


def _two_rooms() -> np.ndarray:
    """4.0 x 2.4 m of navigable floor: two rooms split by a wall at x = 2 m with a 0.6 m door."""
    nav = np.ones((48, 80), dtype=bool)
    nav[:, 39:41] = False
    nav[20:32, 39:41] = True
    return nav


def _lawnmower() -> np.ndarray:
    """Back and forth through both rooms and the door, passes 0.4 m apart: the floor swept by a 0.2 m body."""
    pts = []
    for k, y in enumerate(np.arange(0.2, 2.4, 0.4)):
        xs = (0.2, 1.8) if k % 2 == 0 else (1.8, 0.2)
        pts += [(xs[0], y), (xs[1], y)]
    pts += [(1.8, 1.3), (2.2, 1.3)]  # through the door
    for k, y in enumerate(np.arange(2.2, 0.0, -0.4)):
        xs = (2.2, 3.8) if k % 2 == 0 else (3.8, 2.2)
        pts += [(xs[0], y), (xs[1], y)]
    return np.column_stack([pts, np.zeros(len(pts)), np.zeros(len(pts))])


def test_an_explorer_that_sweeps_every_room_covers_most_of_the_scene():
    nav = _two_rooms()
    assert coverage(_lawnmower(), main_region(nav), RES, (0.0, 0.0), RADIUS) >= 0.8


def test_the_same_path_in_a_scene_twice_as_large_covers_half_as_much():
    small = _two_rooms()
    large = np.concatenate([small, small], axis=1)
    a = coverage(_lawnmower(), main_region(small), RES, (0.0, 0.0), RADIUS)
    b = coverage(_lawnmower(), main_region(large), RES, (0.0, 0.0), RADIUS)
    assert b == pytest.approx(a / 2)


def test_coverage_counts_only_the_main_region():
    nav = _two_rooms()
    nav[:, 39:41] = False  # no door: the left room (x < 1.95 m) is the main region (the lowest id among equals)
    nav[:, 41:] = nav[:, 41:] & (np.arange(39)[None, :] < 30)  # the right room shrinks to an island
    region = main_region(nav)
    assert region[:, :39].all() and not region[:, 41:].any()
    right_only = np.array([[3.0, 0.2, 0, 0], [3.0, 2.2, 0, 0]])
    assert coverage(right_only, region, RES, (0.0, 0.0), RADIUS) == 0.0


def test_a_step_between_two_poses_covers_the_floor_in_between():
    swept = swept_cells(np.array([[0.5, 0.5], [2.5, 0.5]]), (20, 60), RES, (0.0, 0.0), RADIUS)
    assert swept[10, 30] and swept[10, 10:50].all()  # x = 1.525 m, midway, and every cell along the line
    assert not swept[16, 30]  # 0.3 m off the line


def test_a_stationary_explorer_covers_almost_nothing_and_fails():
    nav = _two_rooms()
    still = np.tile([1.0, 1.0, 0.0, 0.0], (200, 1))
    m = score_exploration(still, main_region(nav), RES, (0.0, 0.0), radius=RADIUS, min_coverage=0.25,
                          step_seconds=0.5)
    assert m.coverage < 0.02 and m.sr == 0.0 and m.path_length == 0.0 and m.time == pytest.approx(99.5)


def test_exploration_succeeds_only_with_enough_coverage_and_no_collision():
    nav, path = _two_rooms(), _lawnmower()
    kw = dict(radius=RADIUS, min_coverage=0.5, step_seconds=0.5)
    clean = score_exploration(path, main_region(nav), RES, (0.0, 0.0), **kw)
    c = np.zeros(len(path))
    c[5:8] = 0.3
    bumped = score_exploration(path, main_region(nav), RES, (0.0, 0.0), collision_intensity=c, **kw)
    assert clean.sr == 1.0 and bumped.sr == 0.0 and bumped.collisions == 1.0
    assert bumped.icp == pytest.approx(0.9 / len(path))


def test_a_collision_is_a_run_of_steps_in_contact():
    assert collision_count(np.array([0, 0.2, 0.5, 0, 0, 1, 0, 0.1])) == 3
    assert collision_count(np.array([0.4, 0.0])) == 1 and collision_count(np.zeros(4)) == 0


def _wall_map() -> NavigableMap:
    """3 x 3 m; a wall at y = 1.5 m with a gap only at its far right end."""
    nav = np.ones((60, 60), dtype=bool)
    nav[29:31, :56] = False
    return NavigableMap(nav, RES, (0.0, 0.0), snap_radius=RADIUS)


def test_objectnav_success_and_distance_come_from_the_nearest_viewpoint_on_foot():
    navmap = _wall_map()
    viewpoints = np.zeros(navmap.navigable.shape, dtype=bool)
    viewpoints[40:44, 8:12] = True  # beyond the wall, near x = 0.5 m
    field = navmap.viewpoint_field(viewpoints)
    ref = np.array([[0.5, 0.5], [2.9, 1.5], [0.5, 2.1]])
    behind_wall = np.array([[0.5, 0.5, 0, 0], [0.5, 1.3, 0, 0]])  # 0.7 m in a straight line, ~5 m on foot
    m = score_goal(behind_wall, field, goal_radius=0.0, stopped=True, reference_path=ref)
    assert m.sr == 0.0 and m.osr == 0.0 and m.ne > 4.0
    there = np.array([[0.5, 0.5, 0, 0], [2.9, 0.5, 0, 0], [2.9, 2.1, 0, 0], [0.5, 2.1, 0, 0]])
    m = score_goal(there, field, goal_radius=0.0, stopped=True, reference_path=ref)
    assert m.sr == 1.0 and m.ne == 0.0 and 0.0 < m.spl <= 1.0


def test_a_stationary_agent_never_succeeds_at_a_goal_task():
    navmap = _wall_map()
    field = navmap.field(np.array([2.5, 0.5]))  # a point goal 2 m away, in the same room
    still = np.tile([0.5, 0.5, 0.0, 0.0], (50, 1))
    for stopped in (True, False):
        m = score_goal(still, field, goal_radius=0.2, stopped=stopped, reference_path=np.array([[0.5, 0.5], [2.5, 0.5]]))
        assert m.sr == 0.0 and m.osr == 0.0 and m.spl == 0.0 and m.ne == pytest.approx(2.0)
