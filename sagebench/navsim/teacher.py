"""The oracle's discrete actions along a reference path on an open floor: VLN-CE's ground-truth trajectory.

VLN-CE's recollect trainer replays `{split}_gt.json.gz` actions as teacher forcing and its NDTW measure compares
the agent's positions with the locations they visit. Here the built-in oracle policy (navsim.policies.Oracle,
the one `baseline --agent oracle` runs) drives an ideal agent: MOVE_FORWARD moves exactly forward_step along
the heading, TURN_LEFT / TURN_RIGHT turn exactly turn_deg, nothing collides; it ends with STOP.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sagebench.evaluation.scoring import Episode
from sagebench.navsim.actions import Action
from sagebench.navsim.policies import Oracle
from sagebench.settings.shared import ActionConfig

MAX_ACTIONS = 100_000  # a reference path the oracle has not finished by then is a bug, not a long path


@dataclass(frozen=True)
class TeacherPath:
    actions: tuple[int, ...]  # Action values, the last one STOP
    positions: np.ndarray  # [len(actions) + 1, 3] world metres: the start, then where each action leaves the agent


def teacher_path(episode: Episode, actions: ActionConfig = ActionConfig()) -> TeacherPath:
    """The oracle's actions for `episode` from its start pose, and the positions they visit."""
    oracle = Oracle(actions)
    oracle.begin([episode])
    pose = np.array([*episode.start, episode.start_yaw], dtype=np.float64)
    turn = math.radians(actions.turn_deg)
    taken, positions = [], [pose[:3].copy()]
    while len(taken) < MAX_ACTIONS:
        (action,) = oracle.act([0], [{"pose": pose.copy()}], [{}])
        taken.append(int(action))
        if action == Action.MOVE_FORWARD:
            pose[:2] += actions.forward_step * np.array([math.cos(pose[3]), math.sin(pose[3])])
        elif action in (Action.TURN_LEFT, Action.TURN_RIGHT):
            pose[3] = math.remainder(pose[3] + (turn if action == Action.TURN_LEFT else -turn), 2 * math.pi)
        positions.append(pose[:3].copy())
        if action == Action.STOP:
            return TeacherPath(tuple(taken), np.array(positions))
    raise RuntimeError(f"episode {episode.episode_id}: the oracle took {MAX_ACTIONS} actions without stopping")
