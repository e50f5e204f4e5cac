"""The verdict on one replayed trajectory: metrics (CSR, ICP, PS, ...) and the reasons it fails, if any.

Reasons (a trajectory passes when it has none):
- `collision`: the agent touched a collider and either a contact was deeper than penetration_tolerance, or
  contact pushed it more than deviation_tolerance off the commanded polyline, or contact stopped it short of
  the end (the replay stalled or ran out of time more than deviation_tolerance from the last waypoint).
  Brushes within the maps' precision (paths are planned on 0.05 m cells) move the agent a few centimetres
  and pass.
- `goal_not_reached`: the replay ended farther than goal_radius from the goal (SR = 0).
- `left_corridor`: CSR below min_csr (the agent left the corridor around the reference path).
- `incomplete`: the replay stopped short of the end without any contact (a controller limit, not a collider).
- `instruction_not_executable`: a Base_Action sentence of the trajectory, executed literally from the start pose
  (turn by each stated angle, walk each stated distance), ends farther than goal_radius from the goal or crosses
  a blocked cell of the occupancy map (instructions/execution.py).

A nogoal trajectory (docs/tasks.md) has no goal and its reference path is its start alone: nothing to replay, so
`judge_start` checks the start pose instead, with two reasons:
- `start_off_map`: the start does not stand on a navigable cell of the map's main region (where coverage is
  measured and the agent's centre may stand);
- `collision`: the agent standing at the start touches a collider deeper than penetration_tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from sagebench.instructions.execution import BlockedMap, execute_sentence
from sagebench.metrics import score_episode
from sagebench.metrics.polyline import distance_to_polyline, path_length
from sagebench.replay.physics import ReplayRecord
from sagebench.settings.shared import MetricConfig
from sagebench.settings.validate import CheckConfig

if TYPE_CHECKING:
    from sagebench.episodes.load import Trajectory

REASONS = ("collision", "goal_not_reached", "left_corridor", "incomplete", "instruction_not_executable")
START_REASONS = ("start_off_map",)  # a nogoal trajectory's, besides collision
START_ONLY = "start_only"  # the outcome of a trajectory whose start alone was checked


@dataclass(frozen=True)
class Verdict:
    """Metrics and failure reasons of one replayed trajectory (metres, seconds)."""

    reasons: tuple[str, ...]
    reached_goal: bool | None  # None: no goal (nogoal)
    collision_free: bool
    final_distance: float  # NE
    csr: float
    icp: float
    ps: float
    ndtw: float
    path_length: float  # replayed
    reference_length: float
    max_penetration: float
    max_deviation: float  # farthest replayed pose from the commanded polyline
    contact_steps: int
    steps: int
    duration: float
    outcome: str

    @property
    def passed(self) -> bool:
        return not self.reasons


def judge(
    record: ReplayRecord,
    reference_path: np.ndarray,
    goal: np.ndarray,
    *,
    goal_radius: float,
    geodesic_distance: float,
    timestep: float,
    config: CheckConfig = CheckConfig(),
    metrics: MetricConfig = MetricConfig(),
    executable: bool = True,
) -> Verdict:
    """Score a replay of `reference_path` [M, 4] against `goal` [>=2] and list what is wrong with it;
    `executable`: whether every Base_Action sentence of the trajectory executes literally (see the module)."""
    ref = np.asarray(reference_path, dtype=np.float64)
    scores = score_episode(record.poses, ref, goal, on_foot=None, goal_radius=goal_radius, geodesic_distance=geodesic_distance,
                           stopped=True, collision_intensity=record.intensity, config=metrics)
    deviation = float(distance_to_polyline(record.poses, ref).max())
    end_gap = float(np.linalg.norm(record.poses[-1, :2] - ref[-1, :2]))
    touched = bool(record.contact.any())
    short = record.outcome != "reached" and end_gap > config.deviation_tolerance
    penetration = float(record.penetration.max())
    collision = touched and (penetration > config.penetration_tolerance or deviation > config.deviation_tolerance
                             or short)
    reasons = [name for name, bad in (("collision", collision), ("goal_not_reached", scores.sr < 1.0),
                                      ("left_corridor", scores.csr < config.min_csr),
                                      ("incomplete", short and not touched),
                                      ("instruction_not_executable", not executable)) if bad]
    return Verdict(reasons=tuple(reasons), reached_goal=scores.sr >= 1.0, collision_free=not collision,
                   final_distance=scores.ne, csr=scores.csr, icp=scores.icp, ps=scores.ps, ndtw=scores.ndtw,
                   path_length=scores.path_length, reference_length=path_length(ref), max_penetration=penetration,
                   max_deviation=deviation, contact_steps=int(record.contact.sum()), steps=record.steps,
                   duration=record.steps * timestep, outcome=record.outcome)


def judge_start(*, on_map: bool, penetration: float | None, config: CheckConfig = CheckConfig()) -> Verdict:
    """The verdict on a nogoal trajectory's start pose (module docstring): `on_map`, whether it stands on the main
    region; `penetration`, the agent's deepest contact there (None: it touches nothing). Its path metrics are NaN:
    there is no path and no goal to measure them on."""
    collision = penetration is not None and penetration > config.penetration_tolerance
    nan = float("nan")
    return Verdict(reasons=tuple(name for name, bad in (("collision", collision), ("start_off_map", not on_map))
                                 if bad), reached_goal=None, collision_free=not collision, final_distance=nan,
                   csr=nan, icp=nan, ps=nan, ndtw=nan, path_length=0.0, reference_length=0.0,
                   max_penetration=penetration or 0.0, max_deviation=0.0, contact_steps=int(penetration is not None),
                   steps=0, duration=0.0, outcome=START_ONLY)


def base_action_executable(traj: Trajectory, blocked: BlockedMap) -> bool:
    """Whether every Base_Action sentence of `traj` ends within its goal radius without crossing `blocked`."""
    start = traj.reference_path[0]
    return all(execute_sentence(s, start[:2], float(start[3]), traj.goal[:2], blocked).ok(traj.goal_radius)
               for s in traj.base_action)
