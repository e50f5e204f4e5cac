"""Agents moved by MuJoCo for one action: walls stop them at any speed, c(t) measured, penetration recovered."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from sagebench.navsim.actions import Action, continuous_commands, discrete_commands
from sagebench.navsim.motion import Agents, blocked_share
from sagebench.replay.physics import build_replay_model
from sagebench.settings.rollout import MotionConfig
from sagebench.settings.shared import ActionConfig, ReplayConfig

WALL_X = 2.95  # the room's wall face (conftest.room_mjcf); agent radius 0.2


@pytest.fixture(scope="module")
def room(room_mjcf):
    return build_replay_model(mujoco.MjSpec.from_string(room_mjcf), floor_bodies=["floor_3"])


def test_discrete_actions_move_and_turn_exactly_in_free_space(room):
    cfg = ActionConfig()
    agents = Agents(room, np.array([[0.0, -2.0, 0.0]]))
    for a, want in [(Action.MOVE_FORWARD, [0.25, -2.0, 0.0]), (Action.TURN_LEFT, [0.25, -2.0, math.radians(15)]),
                    (Action.TURN_RIGHT, [0.25, -2.0, 0.0]), (Action.TURN_RIGHT, [0.25, -2.0, -math.radians(15)])]:
        v, omega, stop = discrete_commands(np.array([a]), cfg)
        motion = agents.move(np.array([0]), v, omega, cfg.control_interval)
        assert motion.pose[0] == pytest.approx(want, abs=1e-9)
        assert not motion.collided[0] and motion.intensity[0] == 0.0 and not stop[0]


@pytest.mark.parametrize("space", ["discrete", "continuous"])
def test_a_wall_stops_the_agent_at_any_speed_and_costs_c_1(room, space):
    replay = ReplayConfig()
    cfg = ActionConfig()
    agents = Agents(room, np.array([[2.0, -2.0, 0.0]]))
    if space == "discrete":
        v, omega, _ = discrete_commands(np.array([Action.MOVE_FORWARD]), cfg)
    else:  # the fastest the space allows, and beyond (clipped)
        v, omega, _ = continuous_commands(np.array([[10.0, 0.0, 0.0]]), replay)
        assert v[0] == replay.max_speed
    xs, cs = [], []
    for _ in range(12):
        motion = agents.move(np.array([0]), v, omega, cfg.control_interval)
        xs.append(motion.pose[0, 0])
        cs.append(motion.intensity[0])
    assert max(xs) <= WALL_X - 0.2 + 0.01  # never through, never deeper than the recovery depth
    assert xs[-1] >= WALL_X - 0.2 - 0.01  # it stands against the wall
    assert cs[-1] == pytest.approx(1.0, abs=0.02)  # commanded forward, achieved nothing
    assert 0.0 <= min(cs) and max(cs) <= 1.0


def test_sliding_along_a_wall_costs_the_blocked_share(room):
    agents = Agents(room, np.array([[WALL_X - 0.2, -2.0, math.radians(45)]]))
    motion = agents.move(np.array([0]), np.array([0.5]), np.array([0.0]), 0.5)
    assert motion.collided[0]
    # partly blocked: the drive holds the speed along the heading, so the agent slides along the wall faster
    # than it was asked to move in y and most of the commanded motion comes through (measured c = 0.215)
    assert 0.1 <= motion.intensity[0] <= 0.5
    assert motion.pose[0, 1] > -2.0  # it slid along the wall


def test_a_corner_brushed_mid_step_costs_c_above_0_though_the_end_pose_is_clear(room):
    """Heading 5 degrees right of +x from (0.75, 0), the agent's edge clips the table's corner (1.1, 0.1) on the
    way and is pushed past it: the end pose touches nothing, yet contact slowed the step (measured c = 0.043)."""
    agents = Agents(room, np.array([[0.75, 0.0, math.radians(-5)]]))
    motion = agents.move(np.array([0]), np.array([0.8]), np.array([0.0]), 1.0)
    d = mujoco.MjData(room.model)
    mujoco.mj_setState(room.model, d, agents.state[0], mujoco.mjtState.mjSTATE_FULLPHYSICS)
    mujoco.mj_forward(room.model, d)
    assert d.sensordata[room.sensor] == 0 and motion.pose[0, 0] > 1.1 + 0.2  # clear, and past the corner
    assert motion.collided[0] and motion.intensity[0] > 0.02


def test_an_end_pose_deeper_than_the_recovery_depth_is_undone(room):
    cfg = MotionConfig(recovery_depth=0.0)  # any penetration counts
    agents = Agents(room, np.array([[2.2, -2.0, 0.0]]))
    motion = agents.move(np.array([0]), np.array([0.8]), np.array([0.0]), 1.0, cfg)
    assert motion.recovered[0] and motion.penetration[0] > 0.0
    assert motion.pose[0, 0] < WALL_X - 0.2  # back at the last pose that did not penetrate
    assert motion.pose[0, 0] > 2.2  # which is past the start
    d = mujoco.MjData(room.model)  # the recovered state touches nothing and is at rest
    mujoco.mj_setState(room.model, d, agents.state[0], mujoco.mjtState.mjSTATE_FULLPHYSICS)
    mujoco.mj_forward(room.model, d)
    assert d.sensordata[room.sensor] == 0 and not d.qvel.any()


def test_rows_are_independent_of_each_other(room):
    poses = np.array([[2.0, -2.0, 0.0], [0.0, 0.0, 1.0], [2.5, 2.0, 0.2]])
    together = Agents(room, poses, threads=2)
    alone = [Agents(room, p[None]) for p in poses]
    v, omega = np.array([0.8, 0.3, 0.5]), np.array([0.0, 1.5, -0.4])
    for _ in range(4):
        mt = together.move(np.arange(3), v, omega, 0.5)
        for i in range(3):
            mi = alone[i].move(np.array([0]), v[i:i + 1], omega[i:i + 1], 0.5)
            assert mt.pose[i].tobytes() == mi.pose[0].tobytes()
            assert mt.intensity[i].tobytes() == mi.intensity[0].tobytes()
    assert together.state.tobytes() == np.concatenate([a.state for a in alone]).tobytes()


def test_bad_actions_are_refused():
    with pytest.raises(ValueError, match="discrete actions are 0..3"):
        discrete_commands(np.array([4]), ActionConfig())


@pytest.mark.parametrize("commanded, achieved, turn, turned, touched, c", [
    ((0.25, 0.0), (0.0, 0.0), 0.0, 0.0, True, 1.0),  # a move stopped dead
    ((0.25, 0.0), (0.125, 0.05), 0.0, 0.0, True, 0.5),  # half of it along the commanded direction
    ((0.25, 0.0), (0.0, 0.0), 0.0, 0.0, False, 0.0),  # no contact, no intensity
    ((0.0, 0.0), (0.0, 0.0), 0.26, 0.26, True, 0.0),  # a turn beside a wall that turned in full
    ((0.0, 0.0), (0.001, 0.0), -0.26, -0.13, True, 0.5),  # a turn half blocked
    ((0.0, 0.0), (0.0, 0.0), 0.26, -0.1, True, 1.0),  # turned back: clipped to 1
    ((0.0, 0.0), (0.0, 0.0), 0.0, 0.0, True, 0.0),  # told to stand still
])
def test_blocked_share_known_answers(commanded, achieved, turn, turned, touched, c):
    got = blocked_share(np.array([commanded]), np.array([achieved]), np.array([turn]), np.array([turned]),
                        np.array([touched]))
    assert got[0] == pytest.approx(c)


def test_turning_in_place_against_a_wall_is_not_a_collision(room):
    cfg = ActionConfig()
    agents = Agents(room, np.array([[2.0, -2.0, 0.0]]))
    forward = discrete_commands(np.array([Action.MOVE_FORWARD]), cfg)
    for _ in range(6):  # up against the wall
        motion = agents.move(np.array([0]), *forward[:2], cfg.control_interval)
    assert motion.collided[0] and motion.intensity[0] == pytest.approx(1.0, abs=0.02)
    for action in (Action.TURN_LEFT, Action.TURN_LEFT, Action.TURN_RIGHT):
        motion = agents.move(np.array([0]), *discrete_commands(np.array([action]), cfg)[:2], cfg.control_interval)
        assert motion.collided[0]  # it touches the wall while it turns
        assert motion.intensity[0] == pytest.approx(0.0, abs=1e-9)  # the prism turned in full: nothing blocked it
