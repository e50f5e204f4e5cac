"""The built-in oracle on an open floor with ideal motion: it must reach the end of any reference path.

Its moves are 0.25 m along 15-degree headings, so it can pass a station without ever ending within half a step
of it; on the demo run 18 of 600 episodes turned back and forth round such a station until the step limit.
"""

from __future__ import annotations

import math

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from profiles import examples

from sagebench.episodes.episode import Episode
from sagebench.navsim.actions import Action
from sagebench.navsim.policies import PolicyConfig, built_in, oracle_targets
from sagebench.settings.shared import ActionConfig

ACTIONS = ActionConfig()


def _episode(path_xy: np.ndarray, start_yaw: float = 0.0) -> Episode:
    path = np.column_stack([path_xy, np.zeros(len(path_xy)), np.zeros(len(path_xy))])
    return Episode(episode_id="e", scene_id="s", level="low", type="Base_Action", start=path[0, :3],
                   start_yaw=start_yaw, goal=path[-1, :3], goal_radius=1.0, geodesic_distance=0.0,
                   reference_path=path)


def _walk(episode: Episode, limit: int) -> tuple[np.ndarray, int]:
    """Drive the oracle with exact motion (no physics, nothing in the way): its final pose and actions taken."""
    policy = built_in("oracle", actions=ACTIONS)
    policy.begin([episode])
    pose = np.array([*episode.start[:2], 0.0, episode.start_yaw])
    for n in range(limit):
        action = policy.act([0], [{"pose": pose.copy()}], [{"collision_intensity": 0.0}])[0]
        if action == Action.STOP:
            return pose, n
        if action == Action.MOVE_FORWARD:
            pose[:2] += ACTIONS.forward_step * np.array([math.cos(pose[3]), math.sin(pose[3])])
        else:
            turn = math.radians(ACTIONS.turn_deg) * (1 if action == Action.TURN_LEFT else -1)
            pose[3] = math.remainder(pose[3] + turn, 2 * math.pi)
    return pose, limit


def _bound(path_xy: np.ndarray) -> int:
    """Generous: every station a forward move plus a half turn."""
    length = float(np.linalg.norm(np.diff(path_xy, axis=0), axis=1).sum())
    return int((length / ACTIONS.forward_step + len(path_xy) + 1) * (1 + 180 / ACTIONS.turn_deg)) + 10


def test_the_demo_path_it_circled_on_is_walked_to_its_end():
    path = np.array([[7.825, 5.975], [8.175, 5.975], [8.275, 5.825], [8.275, 4.975], [8.125, 4.875],
                     [6.825, 4.875], [5.525, 6.025]])
    pose, n = _walk(_episode(path), 500)
    assert n < 500 and np.hypot(*(pose[:2] - path[-1])) <= ACTIONS.forward_step


@settings(max_examples=examples(150))
@given(st.lists(st.tuples(st.integers(-6, 6), st.integers(-6, 6)), min_size=1, max_size=6),
       st.floats(-math.pi, math.pi))
@example(steps=[(1, 1), (-1, 0), (1, 0)], start_yaw=0.0)  # ends on its first corner: stopped 0.294 m short
def test_the_oracle_stops_near_the_end_of_any_grid_path(steps, start_yaw):
    """Reference paths with corners on a 0.25 m grid, runs of up to 1.5 m each way, any start heading: the
    oracle stops within one forward step of the end."""
    path = np.cumsum(np.array([(0, 0), *steps], dtype=np.float64) * 0.05 * 5, axis=0)
    pose, n = _walk(_episode(path, start_yaw), _bound(path))
    assert n < _bound(path), "the oracle did not stop"
    assert np.hypot(*(pose[:2] - path[-1])) <= ACTIONS.forward_step


def test_oracle_targets_by_hand():
    t = oracle_targets(np.array([[0, 0], [1, 0], [1, 0.6]]), 0.25)
    np.testing.assert_allclose(t, [[0, 0], [.25, 0], [.5, 0], [.75, 0], [1, 0], [1, .25], [1, .5], [1, .6]])
    # a turn waypoint (same spot) is one point; stations 3 cm before a corner or the end give way; stations
    # stay at multiples of 0.25 m of arc length (those nDTW resamples the reference to)
    np.testing.assert_allclose(oracle_targets(np.array([[0, 0], [0, 0], [0.53, 0], [0.53, 1]]), 0.25),
                               [[0, 0], [.25, 0], [.53, 0], [.53, .22], [.53, .47], [.53, .72], [.53, 1]])


def _random_actions(episodes: list[Episode], seed: int) -> list[list[Action]]:
    policy = built_in("random", seed=seed, config=PolicyConfig(random_min_actions=5, random_max_actions=30))
    policy.begin(episodes)
    out: list[list[Action]] = [[] for _ in episodes]
    pose = {"pose": np.zeros(4)}
    for _ in range(40):
        live = [i for i in range(len(episodes)) if not out[i] or out[i][-1] != Action.STOP]
        acts = policy.act(live, [pose] * len(live), [{"collision_intensity": 0.0}] * len(live))
        for i, a in zip(live, acts):
            out[i].append(a)
    return out


def test_random_walks_are_seeded_per_episode():
    path = np.array([[0.0, 0.0], [1.0, 0.0]])
    eps = [Episode(**{**_episode(path).__dict__, "episode_id": f"r{i}"}) for i in range(3)]
    together = _random_actions(eps, 0)
    assert together == _random_actions(eps, 0) and together[1] == _random_actions([eps[1]], 0)[0]
    assert together[0] != _random_actions(eps, 1)[0] and together[0] != together[2]  # own generator per id
    assert all(w[-1] == Action.STOP and 5 <= len(w) - 1 <= 30 for w in together)
