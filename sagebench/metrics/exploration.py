"""Scores of a no-goal (exploration) episode: coverage, collisions, ICP, path length, time, PS and success.

- coverage   = the share of the main region's navigable cells within the agent's radius of its path (`coverage.py`).
- collisions = the number of contacts: runs of consecutive steps with c(t) > 0 (pressing along a wall for five steps
               is one collision), c(t) the simulator's collision intensity (`evaluation/intensity.py`).
- ICP, PS    = as for VLN (`episode.py`); path length in m; time = steps x the control interval, s.
- SR         = 1 only when coverage >= min_coverage and there was no collision. Stopping, timing out or the goal
               criterion of any other task never makes an exploration a success: SAGE-Bench scored a no-goal
               episode batched with VLN ones by the goal criterion, so an agent that never moved "succeeded"
               (SAGE-3D issue #18), and it counts reaching the time limit as success.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from sagebench.metrics.coverage import coverage
from sagebench.metrics.episode import check_poses, intensities, path_smoothness
from sagebench.metrics.polyline import path_length


@dataclass(frozen=True)
class ExplorationMetrics:
    sr: float
    coverage: float
    collisions: float
    icp: float
    ps: float
    path_length: float
    time: float

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def collision_count(collision_intensity: np.ndarray) -> int:
    """The runs of consecutive nonzero values in c(t) [T]."""
    hit = np.asarray(collision_intensity) > 0
    return int(np.count_nonzero(hit[1:] & ~hit[:-1]) + (len(hit) > 0 and hit[0]))


def score_exploration(poses: np.ndarray, region: np.ndarray, resolution: float, origin: tuple[float, float], *,
                      radius: float, min_coverage: float, step_seconds: float,
                      collision_intensity: np.ndarray | None = None) -> ExplorationMetrics:
    """Score one no-goal episode: poses [T, 4] (x, y, z, yaw); region [H, W] bool the scene's main region on its
    grid (`resolution`, `origin`); radius the agent's, m; step_seconds the control interval, s; collision_intensity
    [T] in [0, 1] (zeros when None)."""
    poses = check_poses(poses)
    c = intensities(collision_intensity, len(poses))
    cov = coverage(poses[:, :2], region, resolution, origin, radius)
    hits = collision_count(c)
    return ExplorationMetrics(sr=float(cov >= min_coverage and hits == 0), coverage=cov, collisions=float(hits),
                              icp=float(c.mean()), ps=path_smoothness(poses[:, 3]), path_length=path_length(poses),
                              time=(len(poses) - 1) * float(step_seconds))
