"""Collision intensity per step, by hand and by replay in the inline test room (wall at x = 2.95..3.05)."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from sagebench.evaluation.intensity import blocked_fraction, derive_intensity, pure_turns, replay_intensity
from sagebench.replay.contact import ContactProbe, contact_share
from sagebench.replay.physics import build_replay_model, replay_one
from sagebench.settings.evaluate import STEP_REPLAY


@pytest.fixture(scope="module")
def rm(room_mjcf):
    return build_replay_model(mujoco.MjSpec.from_string(room_mjcf), floor_bodies=["floor_3"], config=STEP_REPLAY)


def test_blocked_fraction_by_hand():
    start = np.zeros((7, 2))
    target = np.array([[1, 0], [1, 0], [1, 0], [1, 0], [0.01, 0], [1, 0], [0.04, 0]], float)
    end = np.array([[0.25, 0], [0.96, 0.02], [0, 0], [0.5, 0.3], [0, 0], [-0.2, 0], [0, 0]], float)
    c = blocked_fraction(start, target, end, min_step=0.02)
    # stopped a quarter of the way; ended within 5 cm (a brush); stopped dead; pushed sideways half way;
    # a 1 cm step is a turn, not a move; pushed backwards is fully blocked, no more; a 4 cm step stopped dead
    # ends within 5 cm of its target
    np.testing.assert_allclose(c, [0.75, 0.0, 1.0, 0.5, 0.0, 1.0, 0.0])
    assert blocked_fraction(start[:1], target[:1], [[0.97, 0]], min_step=0.02, arrival=0.02)[0] == pytest.approx(0.03)


def test_a_step_into_the_wall_is_blocked_by_the_part_beyond_contact(rm):
    # from x = 2.0 towards x = 3.5: the 0.2 m agent touches the wall face at x = 2.95 when its centre is at 2.75,
    # so 0.75 of the 1.5 m commanded are achieved: c = 0.5 (the 32-gon is up to 1 mm wider than the cylinder)
    poses = np.array([[1.0, -2.0, 0, 0], [2.0, -2.0, 0, 0], [3.5, -2.0, 0, 0], [3.5, -2.0, 0, math.pi / 2]])
    (c,) = replay_intensity(rm, [poses])
    assert c[0] == 0.0 and c[1] == 0.0 and c[3] == 0.0  # the start, free floor, a turn in place
    assert c[2] == pytest.approx(0.5, abs=0.005)


def test_each_step_is_replayed_from_its_predicted_pose(rm):
    # a step through the wall (stopped at 2.75 of 2.3 -> 3.6), then on from the far side as predicted: free
    beyond = np.array([[2.0, -2.0, 0, 0], [2.3, -2.0, 0, 0], [3.6, -2.0, 0, 0], [4.0, -2.0, 0, 0]])
    grazing = np.array([[0.5, 0.5, 0, 0], [1.5, 0.5, 0, 0]])  # into the table (x 1.1..1.9, y 0.1..0.9)
    c_beyond, c_table = replay_intensity(rm, [beyond, grazing])
    assert c_beyond[1] == 0.0 and c_beyond[3] == 0.0
    assert c_beyond[2] == pytest.approx(1 - (2.75 - 2.3) / 1.3, abs=0.005)
    assert c_table[1] == pytest.approx(1 - (1.1 - 0.2 - 0.5) / 1.0, abs=0.005)


def test_dense_poses_through_a_wall_are_caught_where_they_start_inside_it(rm):
    xs = np.arange(2.0, 4.0, 0.04)  # 4 cm steps, shorter than the 5 cm allowance
    poses = np.column_stack([xs, np.full(len(xs), -2.0), np.zeros(len(xs)), np.zeros(len(xs))])
    (c,) = replay_intensity(rm, [poses])
    blocked = xs[c > 0.5]
    assert len(blocked) >= 3 and (blocked > 2.7).all() and (blocked < 3.3).all()


def test_batched_steps_agree_with_one_plain_replay_per_step(rm):
    rng = np.random.default_rng(0)
    xy = np.cumsum(rng.uniform(-0.4, 0.4, size=(12, 2)), axis=0) + [2.0, -1.0]
    poses = np.column_stack([xy, np.zeros(12), np.zeros(12)])
    (c,) = replay_intensity(rm, [poses])
    plain = [0.0]
    for a, b in zip(xy[:-1], xy[1:]):
        yaw = math.atan2(b[1] - a[1], b[0] - a[0])
        end = replay_one(rm, np.array([[*a, 0, yaw], [*b, 0, yaw]])).poses[-1, :2]
        plain.append(float(blocked_fraction(a[None], b[None], end[None], min_step=rm.config.waypoint_tolerance)[0]))
    np.testing.assert_allclose(c, plain, atol=1e-12)
    assert (c > 0).any()  # the walk crosses the wall at x = 2.95


def test_contact_share_counts_positions_within_the_contact_distance(rm):
    # the agent (radius 0.2, its 32-gon up to 1 mm wider) beside the wall face x = 2.95: clear at a gap of 1.5 cm,
    # touching at 0.5 cm (CONTACT_DISTANCE 1 cm); a step that stays put counts its one pose
    clear, touch = 2.95 - 0.2 - 0.015, 2.95 - 0.2 - 0.005
    still = np.array([[clear, -2.0, 0, 0], [clear, -2.0, 0, 1.0], [touch, -2.0, 0, 1.0], [touch, -2.0, 0, 2.0]])
    (c,) = contact_share(rm, [still])
    assert c.tolist() == [0.0, 0.0, pytest.approx(0.5), 1.0]  # start; turn in the clear; half the move; pressed
    # along the wall for 1 m (51 positions 2 cm apart, all touching), then 0.19 m away from it (1 of 11 touches)
    along = np.array([[touch, -2.0, 0, 0], [touch, -1.0, 0, 0], [touch - 0.19, -1.0, 0, 0]])
    (c,) = contact_share(rm, [along])
    assert c[1] == 1.0 and c[2] == pytest.approx(1 / 11)
    free = np.array([[0.0, -2.0, 0, 0], [0.5, -2.5, 0, 0]])
    assert contact_share(rm, [free])[0].tolist() == [0.0, 0.0]


def test_a_derived_turn_in_place_counts_no_contact_but_pressing_does(rm):
    touch = 2.95 - 0.2 - 0.005  # within the contact distance of the wall
    poses = np.array([[touch, -2.0, 0, 0.0], [touch, -2.0, 0, 0.26], [touch, -2.0, 0, 0.26], [touch, -2.0, 0, -0.1]])
    assert pure_turns(poses, min_step=rm.config.waypoint_tolerance).tolist() == [False, True, False, True]
    (c,) = derive_intensity(rm, [poses])
    assert c.tolist() == [0.0, 0.0, 1.0, 0.0]  # turn; pressed (no move, no turn); turn
    assert contact_share(rm, [poses])[0].tolist() == [0.0, 1.0, 1.0, 1.0]  # what contact alone counted before


def test_a_probe_kept_open_answers_each_call_as_a_fresh_one(rm):
    """The env keeps one ContactProbe per scene and asks it every step: its MjData carry nothing from one call
    to the next (warm start included), so each answer is contact_share's on those poses alone."""
    touch = 2.95 - 0.2 - 0.005
    walks = [np.array([[touch, -2.0], [touch, -1.0], [touch - 0.19, -1.0]]), np.array([[0.0, -2.0], [0.5, -2.5]]),
             np.array([[2.0, -1.0], [2.9, -1.0]]), np.array([[touch, 0.0], [touch, 0.0]])]
    probe = ContactProbe(rm, threads=2)
    for _ in range(2):
        for k in range(len(walks)):
            ask = walks[k:] + walks[:k]
            got = probe.shares(ask)
            assert [g.tobytes() for g in got] == [c.tobytes() for c in contact_share(rm, ask)]
    assert probe.shares([]) == [] and probe.shares([walks[0][:1]])[0].tolist() == [0.0]
