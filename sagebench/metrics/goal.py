"""Scores of a goal task's episode (ObjectNav, PointNav, ImageNav): SR, OSR, SPL, NE, plus CSR, ICP and PS.

Every distance to the goal is read from one field on the scene's navigable map (`on_foot.py`): the distance on foot
to the goal point (PointNav, ImageNav) or to the nearest goal viewpoint (ObjectNav). Success, NE, OSR and SPL's
shortest distance g (the field at the start) all read it, so success and the distance to the goal cannot disagree
(SAGE-Bench decides ObjectNav success through a second, scene-dependent 2D mapping: 0.41 m from the goal "failed"
while 2.18 m "succeeded", SAGE-3D issue #10).
- NE  = the field at the final pose; a final pose that cannot reach the goal gets the field's worst value.
- SR  = 1 if the agent stopped with NE <= goal_radius; OSR = 1 if any pose came within goal_radius.
- SPL = SR * g / max(g, L), g the field at the start, L the path length.
- CSR = mean over poses of 1 while within r_tol of the reference path (the shortest path to the goal); ICP and PS
  as for VLN (`episode.py`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from sagebench.metrics.episode import check_poses, intensities, path_smoothness, success_weighted
from sagebench.metrics.on_foot import GoalField, ViewpointField
from sagebench.metrics.polyline import distance_to_polyline, path_length, resample
from sagebench.settings.shared import MetricConfig


@dataclass(frozen=True)
class GoalMetrics:
    sr: float
    osr: float
    spl: float
    ne: float
    csr: float
    icp: float
    ps: float
    path_length: float

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def score_goal(poses: np.ndarray, field: GoalField | ViewpointField, *, goal_radius: float, stopped: bool,
               reference_path: np.ndarray, collision_intensity: np.ndarray | None = None,
               config: MetricConfig = MetricConfig()) -> GoalMetrics:
    """Score one goal-task episode: poses [T, 4] (x, y, z, yaw), `field` the goal's distances on foot,
    reference_path [M, >=2] the shortest path, collision_intensity [T] in [0, 1] (zeros when None)."""
    poses = check_poses(poses)
    dist = field.distance(poses[:, :2])
    ne = float(dist[-1]) if np.isfinite(dist[-1]) else field.worst
    sr = float(stopped and ne <= goal_radius)
    g = float(dist[0]) if np.isfinite(dist[0]) else field.worst
    length = path_length(poses)
    ref = resample(np.asarray(reference_path, dtype=np.float64), config.resample_spacing)
    csr = float((distance_to_polyline(poses, ref) <= config.corridor_radius).mean())
    return GoalMetrics(sr=sr, osr=float((dist <= goal_radius).any()), spl=success_weighted(sr, g, length), ne=ne,
                       csr=csr, icp=float(intensities(collision_intensity, len(poses)).mean()),
                       ps=path_smoothness(poses[:, 3]), path_length=length)
