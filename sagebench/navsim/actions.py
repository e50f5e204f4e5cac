"""The two action spaces: VLN-CE's discrete actions and continuous (v, omega), both as commands held for one
control interval.

Discrete: STOP ends the episode; MOVE_FORWARD drives forward_step metres, TURN_LEFT / TURN_RIGHT turn turn_deg
degrees counter-clockwise / clockwise, each at the constant speed that takes exactly one control interval.
Continuous: [v m/s, omega rad/s, stop], v in [0, max_speed], omega within +-max_turn_rate (the replay's
limits, which the drive can hold against a wall without tunnelling); stop >= 0.5 ends the episode.
"""

from __future__ import annotations

import math
from enum import IntEnum

import numpy as np

from sagebench.settings.shared import ActionConfig, ReplayConfig


class Action(IntEnum):
    STOP = 0
    MOVE_FORWARD = 1
    TURN_LEFT = 2
    TURN_RIGHT = 3


def discrete_commands(actions: np.ndarray, config: ActionConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """[B] Action values -> v [B] m/s, omega [B] rad/s, stop [B] bool; a value outside the enum is a ValueError."""
    a = np.asarray(actions).reshape(-1)
    if not np.isin(a, [int(x) for x in Action]).all():
        raise ValueError(f"discrete actions are 0..3 (STOP, MOVE_FORWARD, TURN_LEFT, TURN_RIGHT), got {a.tolist()}")
    rate = math.radians(config.turn_deg) / config.control_interval
    v = np.where(a == Action.MOVE_FORWARD, config.forward_step / config.control_interval, 0.0)
    omega = np.where(a == Action.TURN_LEFT, rate, np.where(a == Action.TURN_RIGHT, -rate, 0.0))
    return v, omega, a == Action.STOP


def continuous_commands(values: np.ndarray, replay: ReplayConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """[B, 3] (v, omega, stop) -> v and omega clipped to the agent's limits, stop [B] bool."""
    x = np.asarray(values, dtype=np.float64).reshape(-1, 3)
    if not np.isfinite(x).all():
        raise ValueError("continuous actions must be finite")
    v = np.clip(x[:, 0], 0.0, replay.max_speed)
    omega = np.clip(x[:, 1], -replay.max_turn_rate, replay.max_turn_rate)
    return v, omega, x[:, 2] >= 0.5
