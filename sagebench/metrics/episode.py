"""Scores of one episode: the navigation metrics of habitat/VLN-CE and the SAGE-Bench continuity metrics.

Definitions (docs/metrics.md; all distances in the XY plane):
- NE  = distance on foot (`on_foot.py`) from the final pose to the goal; a final pose that cannot reach the goal
        gets the largest distance on foot from the goal to any navigable cell (the worst NE on that map).
- NE_STRAIGHT = the straight distance from the final pose to the goal (reported, never used for success).
- SR  = 1 if the agent stopped (`stopped`) with NE <= goal_radius, else 0.
- OSR = 1 if any pose came within goal_radius of the goal on foot.
- SPL = SR * g / max(g, L): g the geodesic start->goal distance, L the agent's path length.
- nDTW = exp(-DTW(P, R) / (|R| * d_th)), d_th = 3.0 m, R the reference resampled every 0.25 m.
- SDTW = SR * nDTW.
- CSR = mean over poses of s(t): 1 while the pose is within r_tol (1.0 m) of the resampled reference polyline.
- ICP = mean over poses of c(t) in [0, 1], the collision intensity (fraction of commanded motion blocked).
- PS  = 1 - mean over t >= 2 of min(|wrap(theta_t - theta_{t-1})| / pi, 1); 1 for a single pose.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from sagebench.metrics.dtw import dtw
from sagebench.metrics.on_foot import GoalField
from sagebench.metrics.polyline import distance_to_polyline, path_length, resample
from sagebench.settings.shared import MetricConfig


@dataclass(frozen=True)
class EpisodeMetrics:
    ne: float
    ne_straight: float
    sr: float
    osr: float
    spl: float
    ndtw: float
    sdtw: float
    csr: float
    icp: float
    ps: float
    path_length: float

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return (np.asarray(a, dtype=np.float64) + np.pi) % (2 * np.pi) - np.pi


def path_smoothness(yaw: np.ndarray) -> float:
    """PS of a yaw sequence [T] in radians."""
    yaw = np.asarray(yaw, dtype=np.float64)
    if len(yaw) < 2:
        return 1.0
    turn = np.abs(wrap_angle(np.diff(yaw)))
    return float(1.0 - np.minimum(turn / math.pi, 1.0).mean())


def intensities(collision_intensity: np.ndarray | None, n: int) -> np.ndarray:
    """c(t) [n] clipped to [0, 1] (zeros when None); ValueError unless there is one value per pose."""
    if collision_intensity is None:
        return np.zeros(n)
    c = np.asarray(collision_intensity, dtype=np.float64)
    if c.shape != (n,):
        raise ValueError(f"collision_intensity must have one value per pose ({n}), got {c.shape}")
    return np.clip(c, 0.0, 1.0)


def success_weighted(sr: float, geodesic: float, length: float) -> float:
    """SPL of one episode: sr * g / max(g, L) (sr itself when both are 0)."""
    g = float(geodesic)
    return sr * g / max(g, length) if max(g, length) > 0 else sr


def check_poses(poses: np.ndarray) -> np.ndarray:
    """poses as a float [T, 4] array, T >= 1; ValueError otherwise."""
    poses = np.asarray(poses, dtype=np.float64)
    if poses.ndim != 2 or poses.shape[1] != 4 or len(poses) == 0:
        raise ValueError(f"poses must be [T, 4] with T >= 1, got shape {poses.shape}")
    return poses


def score_episode(
    poses: np.ndarray,
    reference_path: np.ndarray,
    goal: np.ndarray,
    *,
    on_foot: GoalField | None,
    goal_radius: float,
    geodesic_distance: float,
    stopped: bool,
    collision_intensity: np.ndarray | None = None,
    config: MetricConfig = MetricConfig(),
) -> EpisodeMetrics:
    """Score one episode.

    poses: [T, 4] agent (x, y, z, yaw) as given; reference_path: [M, >=2] waypoints; goal: [>=2];
    collision_intensity: [T] in [0, 1] (zeros when None); on_foot: the goal's distances on foot, or None where
    there is no map (then every distance is the straight one: an open floor).
    """
    poses = check_poses(poses)
    goal_xy = np.asarray(goal, dtype=np.float64)[:2]
    straight = np.linalg.norm(poses[:, :2] - goal_xy, axis=1)
    dist_to_goal = straight if on_foot is None else on_foot.distance(poses[:, :2])
    ne = float(dist_to_goal[-1]) if np.isfinite(dist_to_goal[-1]) else on_foot.worst
    sr = float(stopped and ne <= goal_radius)
    osr = float((dist_to_goal <= goal_radius).any())
    length = path_length(poses)
    spl = success_weighted(sr, geodesic_distance, length)
    ref = resample(np.asarray(reference_path, dtype=np.float64), config.resample_spacing)
    ndtw = math.exp(-dtw(poses, ref) / (len(ref) * config.ndtw_threshold))
    csr = float((distance_to_polyline(poses, ref) <= config.corridor_radius).mean())
    icp = float(intensities(collision_intensity, len(poses)).mean())
    return EpisodeMetrics(ne=ne, ne_straight=float(straight[-1]), sr=sr, osr=osr, spl=spl, ndtw=ndtw, sdtw=sr * ndtw, csr=csr, icp=icp,
                          ps=path_smoothness(poses[:, 3]), path_length=length)
