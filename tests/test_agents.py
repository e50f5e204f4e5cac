"""Baseline policies driven in the inline test room (wall at x = 2.95..3.05, table x 1.1..1.9, y 0.1..0.9)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from sagebench.agents.driver import drive
from sagebench.agents.policies import Oracle, PolicyConfig, RandomWalk, Straight, make_policy, oracle_targets
from sagebench.evaluation.intensity import STEP_REPLAY
from sagebench.evaluation.scoring import Episode, score_prediction
from sagebench.replay.physics import build_replay_model


@pytest.fixture(scope="module")
def rm(room_mjcf):
    return build_replay_model(mujoco.MjSpec.from_string(room_mjcf), floor_bodies=["floor_3"], config=STEP_REPLAY)


def _episode(eid: str, path, radius: float = 1.0) -> Episode:
    p = np.array([[x, y, 0.0, 0.0] for x, y in path])
    d = np.diff(p[:, :2], axis=0)
    p[:-1, 3] = np.arctan2(d[:, 1], d[:, 0])
    return Episode(episode_id=eid, scene_id="room", level="low", type="Single_Goal", start=p[0, :3],
                   start_yaw=float(p[0, 3]), goal=p[-1, :3], goal_radius=radius,
                   geodesic_distance=float(np.linalg.norm(d, axis=1).sum()), reference_path=p)


AROUND_TABLE = [(0.5, -0.5), (2.3, -0.5), (2.3, 1.5), (0.5, 1.5)]  # 0.3 m+ clear of the table and the wall
THROUGH_WALL = [(2.1, -2.0), (4.0, -2.0)]


def test_oracle_targets_by_hand():
    t = oracle_targets(np.array([[0, 0], [1, 0], [1, 0.6]]), 0.25)
    np.testing.assert_allclose(t, [[0, 0], [.25, 0], [.5, 0], [.75, 0], [1, 0], [1, .25], [1, .5], [1, .6]])
    # a turn waypoint (same spot) is one point; stations 3 cm before a corner or the end give way; stations
    # stay at multiples of 0.25 m of arc length (those nDTW resamples the reference to)
    np.testing.assert_allclose(oracle_targets(np.array([[0, 0], [0, 0], [0.53, 0], [0.53, 1]]), 0.25),
                               [[0, 0], [.25, 0], [.53, 0], [.53, .22], [.53, .47], [.53, .72], [.53, 1]])


def test_oracle_follows_the_reference_exactly(rm):
    e = _episode("o", AROUND_TABLE)
    (p,) = drive(rm, [e], Oracle([e], PolicyConfig()), max_actions=100)
    assert p.stopped and len(p.poses) == len(oracle_targets(e.reference_path, 0.25))
    np.testing.assert_allclose(np.array(p.poses)[:, :2], oracle_targets(e.reference_path, 0.25), atol=0.02)
    assert max(p.collision_intensity) == 0.0
    m = score_prediction(e, p, np.asarray(p.collision_intensity), on_foot=None)
    assert (m.sr, m.csr, m.icp) == (1.0, 1.0, 0.0)
    # measured 0.99860: only the corner poses (on the corners, not at 0.25 m of arc) are off the resampled reference
    assert m.spl == pytest.approx(1.0, abs=1e-6) and m.ndtw == pytest.approx(0.9986, abs=2e-4)
    # the two 90-degree corners are nearly all the turning: PS = 1 - (2 * 0.5) / (T - 1)
    assert m.ps == pytest.approx(1 - 1.0 / (len(p.poses) - 1), abs=0.005)


def test_straight_reaches_an_open_goal_and_stops_within_the_radius(rm):
    e = _episode("s", [(-2.0, -2.0), (1.0, -2.0)])
    (p,) = drive(rm, [e], Straight([e], PolicyConfig()), max_actions=100)
    # 3 m to go, 0.25 m per action: it stops after 8 actions, exactly 1 m (the radius) from the goal
    assert p.stopped and len(p.poses) == 9
    assert p.poses[-1][:2] == pytest.approx((0.0, -2.0), abs=1e-3)
    assert max(p.collision_intensity) == 0.0


def test_straight_pushes_into_the_wall_then_gives_up(rm):
    e = _episode("w", THROUGH_WALL)
    config = PolicyConfig()
    (p,) = drive(rm, [e], Straight([e], config), max_actions=100)
    poses, c = np.array(p.poses), np.array(p.collision_intensity)
    assert p.stopped  # stuck: it stops by itself, far from the goal
    assert poses[-1, 0] == pytest.approx(2.75, abs=0.005)
    # 2.1 -> 2.35 -> 2.6 free; 2.6 -> 2.85 stops at 2.75 (the 0.2 m agent against the face at 2.95): 0.4 blocked;
    # then stall_patience moves in a row are stopped dead
    np.testing.assert_allclose(c, [0, 0, 0, 0.4] + [1.0] * config.stall_patience, atol=0.01)
    m = score_prediction(e, p, c, on_foot=None)
    assert m.sr == 0.0 and m.icp == pytest.approx(c.mean()) and m.icp > 0.3


def test_the_action_budget_ends_an_episode_unstopped(rm):
    e = _episode("o", AROUND_TABLE)
    (p,) = drive(rm, [e], Oracle([e], PolicyConfig()), max_actions=3)
    assert not p.stopped and len(p.poses) == 4


def test_random_walks_are_seeded_per_episode(rm):
    eps = [_episode(f"r{i}", AROUND_TABLE) for i in range(3)]
    config = PolicyConfig(random_min_actions=5, random_max_actions=30)

    def run(episodes, seed):
        return drive(rm, episodes, RandomWalk(episodes, config, seed=seed), max_actions=100)

    together = run(eps, 0)
    assert together == run(eps, 0)
    assert together[1] == run([eps[1]], 0)[0]  # the same walk alone as in company
    assert together[0].poses != run(eps, 1)[0].poses
    assert together[0].poses != together[1].poses  # each episode id has its own generator
    for p in together:
        assert p.stopped and 5 <= len(p.poses) - 1 <= 30
        turns = np.abs(np.diff(np.unwrap(np.array(p.poses)[:, 3])))
        assert ((turns < 1e-3) | (turns > math.radians(15) - 1e-3)).all()  # moves keep heading; turns >= 15 deg


def test_make_policy_names():
    e = [_episode("x", AROUND_TABLE)]
    assert isinstance(make_policy("straight", e, PolicyConfig(), seed=0), Straight)
    with pytest.raises(ValueError, match="unknown agent 'walk'"):
        make_policy("walk", e, PolicyConfig(), seed=0)
