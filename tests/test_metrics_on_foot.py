"""Success on foot: a stop near the goal but behind a wall is not a success; missing episodes never help a mean."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from profiles import examples

from sagebench.episodes.episode import Episode
from sagebench.evaluation.predictions import Prediction
from sagebench.evaluation.scoring import (
    METRIC_NAMES, EpisodeScore, missing_metrics, score_prediction, summarise_scores,
)
from sagebench.metrics import NavigableMap, distance_on_foot
from sagebench.metrics.on_foot import distances_on_foot

RES = 0.05
# a 6 m x 4 m flat: bathroom (x < 2.9) and kitchen (x > 3.1) split by a wall x in [2.9, 3.1] from y = 0 to
# y = 3.2; the doorway is the gap above it (y > 3.2). Navigable = free minus nothing else (cell centres).
H, W = 80, 120
NAV = np.ones((H, W), dtype=np.uint8)
NAV[:64, 58:62] = 0  # cols 58..61 = x in [2.9, 3.1), rows 0..63 = y in [0, 3.2)
GOAL = np.array([3.5, 1.0, 0.0])  # in the kitchen
CORNER_BATH, CORNER_KITCHEN = np.array([2.875, 3.225]), np.array([3.125, 3.225])  # doorway corners (cell centres)


def _around(p: np.ndarray) -> float:
    """Shortest walk from p (bathroom) to GOAL round the wall's end: straight legs via both corners."""
    return float(np.linalg.norm(p - CORNER_BATH) + np.linalg.norm(CORNER_BATH - CORNER_KITCHEN)
                 + np.linalg.norm(CORNER_KITCHEN - GOAL[:2]))


def _episode(eid: str = "e") -> Episode:
    path = np.array([[0.5, 1.0, 0, 0], [2.5, 3.5, 0, 0], [3.5, 3.5, 0, 0], [3.5, 1.0, 0, 0]])
    return Episode(episode_id=eid, scene_id="s", level="low", type="Single_Goal", start=np.array([0.5, 1.0, 0]),
                   start_yaw=0.0, goal=GOAL, goal_radius=1.0, geodesic_distance=6.0, reference_path=path)


def _prediction(xy, stopped=True, eid="e") -> Prediction:
    return Prediction(episode_id=eid, poses=[(x, y, 0.0, 0.0) for x, y in xy], stopped=stopped,
                      collision_intensity=[0.0] * len(xy))


def test_a_stop_in_the_bathroom_near_a_kitchen_goal_is_no_success():
    field = distance_on_foot(NAV, RES, (0.0, 0.0), GOAL, snap_radius=0.2)
    stop = np.array([2.6, 1.0])  # 0.9 m straight from the goal, through the wall
    p = _prediction([(0.5, 1.0), (1.5, 1.0), tuple(stop)])
    m = score_prediction(_episode(), p, np.zeros(3), on_foot=field)
    assert m.ne_straight == pytest.approx(0.9)
    # 8-connected walk: never shorter than the any-angle walk round the wall, at most 8.3 % longer (+ one cell)
    assert _around(stop) <= m.ne <= 1.083 * _around(stop) + RES
    assert (m.sr, m.osr, m.spl, m.sdtw) == (0.0, 0.0, 0.0, 0.0)
    # scored the old way (straight distance) the same stop was a success
    assert score_prediction(_episode(), p, np.zeros(3), on_foot=None).sr == 1.0


def test_a_clear_line_to_the_goal_is_the_straight_distance_and_succeeds():
    field = distance_on_foot(NAV, RES, (0.0, 0.0), GOAL, snap_radius=0.2)
    np.testing.assert_allclose(field.distance(np.array([[4.3, 1.6], [3.5, 1.0], [5.9, 3.9]])),
                               [1.0, 0.0, math.hypot(2.4, 2.9)])
    m = score_prediction(_episode(), _prediction([(0.5, 1.0), (2.5, 3.5), (4.3, 1.6)]), np.zeros(3), on_foot=field)
    assert m.sr == 1.0 and m.ne == pytest.approx(1.0)


def test_each_agents_distance_to_its_own_goal_is_what_it_alone_gets():
    """The env asks for every agent at once, each walking to its own goal: each answer is that point's alone,
    whatever else is asked with it (a long segment beside a short one samples neither differently)."""
    navmap = NavigableMap(NAV, RES, (0.0, 0.0), snap_radius=0.2)
    goals = [navmap.field(GOAL), navmap.field(np.array([0.5, 0.5])), navmap.field(GOAL)]
    xy = np.array([[2.6, 1.0], [5.5, 3.7], [4.3, 1.6]])  # behind the wall; far across the flat; in clear sight
    got = distances_on_foot(goals, xy)
    alone = [float(f.distance(p[None])[0]) for f, p in zip(goals, xy)]
    assert got.tobytes() == np.array(alone).tobytes()
    assert got[2] == pytest.approx(1.0) and got[0] > 2.0  # straight where clear, round the wall where not
    far = np.array([[5.9, 0.1], [0.1, 0.1]])  # the second segment crosses the wall, the first is short and clear
    assert navmap.clear_to(far, np.array([[5.8, 0.2], [5.9, 0.1]])).tolist() == [True, False]
    with pytest.raises(ValueError, match="one goal field per point, got 3 for 2 points"):
        distances_on_foot(goals, xy[:2])
    other = NavigableMap(NAV, RES, (0.0, 0.0), snap_radius=0.2).field(GOAL)
    with pytest.raises(ValueError, match="different maps"):
        distances_on_foot([goals[0], other], xy[:2])


def test_a_pose_pressed_into_the_wall_snaps_back_within_the_agent_radius():
    navmap = NavigableMap(NAV, RES, (0.0, 0.0), snap_radius=0.2)
    field = navmap.field(GOAL)
    into_wall = np.array([[3.14, 1.0]])  # in the wall's last column, 0.035 m from the kitchen's first cell centre
    assert field.distance(into_wall)[0] == pytest.approx(math.hypot(0.36, 0.0))
    far = NavigableMap(NAV, RES, (0.0, 0.0), snap_radius=0.01).field(GOAL)
    assert np.isinf(far.distance(np.array([[3.0, 1.0]]))[0])  # the wall's middle: 0.075 m from any navigable cell
    assert np.isinf(field.distance(np.array([[-1.0, 1.0]]))[0])  # off the map


def test_an_unreachable_final_pose_gets_the_worst_distance_on_foot():
    sealed = NAV.copy()
    sealed[64:, 58:62] = 0  # close the doorway: the bathroom cannot reach the kitchen
    field = distance_on_foot(sealed, RES, (0.0, 0.0), GOAL, snap_radius=0.2)
    m = score_prediction(_episode(), _prediction([(0.5, 1.0), (2.6, 1.0)]), np.zeros(2), on_foot=field)
    assert m.sr == 0.0 and m.ne == field.worst


def test_the_worst_distance_is_the_farthest_kitchen_corner_on_the_grid():
    field = distance_on_foot(NAV, RES, (0.0, 0.0), GOAL, snap_radius=0.2)
    # from the goal cell (row 20, col 70) to the bathroom's far corner (row 0, col 0) round the wall: checked
    # against the cell-by-cell 8-connected distance, independent of Dijkstra
    def octile(a, b):
        dr, dc = abs(a[0] - b[0]), abs(a[1] - b[1])
        return (max(dr, dc) - min(dr, dc) + math.sqrt(2) * min(dr, dc)) * RES
    via = octile((20, 70), (64, 62)) + octile((64, 62), (64, 57)) + octile((64, 57), (0, 0))
    assert field.worst == pytest.approx(via, abs=1e-9)
    m = missing_metrics(field)
    assert m.ne == field.worst and m.ne_straight == pytest.approx(math.hypot(3.475, 2.975))  # to cell (79, 0)
    assert (m.sr, m.osr, m.spl, m.ndtw, m.sdtw, m.csr, m.ps, m.icp) == (0, 0, 0, 0, 0, 0, 0, 1)


_XY = st.tuples(st.floats(0.05, 5.95), st.floats(0.05, 3.95))
_BETTER_HIGH = ("sr", "osr", "spl", "ndtw", "sdtw", "csr", "ps")


@settings(max_examples=examples(40))
@given(st.lists(st.tuples(st.lists(_XY, min_size=1, max_size=6), st.booleans(),
                          st.lists(st.floats(0, 1), min_size=6, max_size=6)), min_size=1, max_size=5),
       st.data())
def test_removing_episodes_never_improves_any_mean(runs, data):
    navmap = NavigableMap(NAV, RES, (0.0, 0.0), snap_radius=0.2)
    field = navmap.field(GOAL)
    scores = []
    for i, (xy, stopped, c) in enumerate(runs):
        e = _episode(f"e{i}")
        p = _prediction([(0.5, 1.0), *xy], stopped, f"e{i}")
        scores.append(EpisodeScore(e, score_prediction(e, p, np.asarray(c[:len(xy) + 1] + [0] * 6)[:len(xy) + 1],
                                                       on_foot=field), missing=False, icp_source="self-reported"))
    dropped = data.draw(st.sets(st.integers(0, len(runs) - 1)))
    with_missing = [EpisodeScore(s.episode, missing_metrics(field), missing=True, icp_source="missing")
                    if i in dropped else s for i, s in enumerate(scores)]
    full, partial = summarise_scores(scores).overall, summarise_scores(with_missing).overall
    for m in METRIC_NAMES:
        if m in _BETTER_HIGH:
            assert partial[m] <= full[m] + 1e-12, m
        elif m in ("ne", "ne_straight", "icp"):
            assert partial[m] >= full[m] - 1e-12, m
