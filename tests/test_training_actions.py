"""The discrete actions along a reference path (SAGE-3D's derivation: turn towards each segment, then move)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from sagebench.navsim.actions import Action
from sagebench.settings.shared import ActionConfig
from sagebench.training.actions import path_actions

M, L, R, S = Action.MOVE_FORWARD, Action.TURN_LEFT, Action.TURN_RIGHT, Action.STOP


def test_a_straight_metre_facing_it_is_four_moves():
    assert path_actions(np.array([[0.0, 0.0], [1.0, 0.0]]), 0.0) == [M, M, M, M, S]


def test_a_corner_turns_before_moving_on():
    path = np.array([[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [1.0, 0.5, 0.0, 0.0]])
    assert path_actions(path, 0.0) == [M] * 4 + [L] * 6 + [M] * 2 + [S]
    assert path_actions(path * [1, -1, 1, 1], 0.0) == [M] * 4 + [R] * 6 + [M] * 2 + [S]


def test_the_start_heading_is_turned_to_the_path_first():
    assert path_actions(np.array([[0.0, 0.0], [0.0, -0.5]]), math.pi) == [L] * 6 + [M, M, S]


def test_remainders_carry_over_and_a_last_half_step_is_walked():
    assert path_actions(np.array([[0.0, 0.0], [0.6, 0.0]]), 0.0) == [M, M, S]  # 0.1 m left: under half a step
    assert path_actions(np.array([[0.0, 0.0], [0.65, 0.0]]), 0.0) == [M, M, M, S]
    # 0.15 + 0.15 m along two segments: the carried 0.15 makes the second segment's move
    assert path_actions(np.array([[0.0, 0.0], [0.15, 0.0], [0.15, 0.15]]), 0.0) == [L] * 6 + [M, S]


def test_other_step_sizes():
    config = ActionConfig(forward_step=0.5, turn_deg=30.0, control_interval=1.0)
    assert path_actions(np.array([[0.0, 0.0], [0.0, 1.0]]), 0.0, config) == [L, L, L, M, M, S]


points = st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5)), min_size=2, max_size=8)


@given(points, st.floats(-math.pi, math.pi))
def test_moves_cover_the_path_and_turns_end_on_its_last_heading(pts, start_yaw):
    """Moves add up to the path's length within half a step, and the turns leave the agent facing the last
    segment's direction within half a turn."""
    path = np.array(pts)
    actions = path_actions(path, start_yaw)
    assert actions[-1] == S and S not in actions[:-1]
    seg = np.diff(path, axis=0)
    length = np.hypot(seg[:, 0], seg[:, 1])
    assert abs(actions.count(M) * 0.25 - length.sum()) <= 0.125 + 1e-9
    moving = seg[length > 1e-9]
    if len(moving):
        heading = start_yaw + math.radians(15) * (actions.count(L) - actions.count(R))
        last = math.atan2(moving[-1, 1], moving[-1, 0])
        assert abs((heading - last + math.pi) % (2 * math.pi) - math.pi) <= math.radians(7.5) + 1e-9
