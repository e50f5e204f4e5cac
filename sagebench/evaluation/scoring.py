"""Score predictions against episodes and aggregate: overall, per instruction level and per type, plain means.

An episode without a prediction (evaluate --allow-missing) counts as a failure at every metric's worst value:
SR, OSR, SPL, nDTW, SDTW, CSR and PS 0, ICP 1, path length 0 and NE the largest distance on foot from the goal to
any navigable cell (NE_STRAIGHT the largest straight distance to one), so a missing prediction can only lower a score.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from sagebench.episodes.episode import Episode
from sagebench.evaluation.predictions import Prediction
from sagebench.metrics import EpisodeMetrics, NavigableMap, score_episode
from sagebench.metrics.on_foot import GoalField
from sagebench.settings.shared import MetricConfig

METRIC_NAMES = ("sr", "osr", "spl", "ne", "ne_straight", "ndtw", "sdtw", "csr", "icp", "ps", "path_length")
# which distance to the goal each metric stands on (evaluate reports this with the scores)
DISTANCE_USED = {"sr": "on_foot", "osr": "on_foot", "spl": "on_foot (success)", "ne": "on_foot",
                 "ne_straight": "straight", "sdtw": "on_foot (success)"}
# who measured an episode's c(t): sagebench rollout's simulator, the agent itself, or evaluate's replay of the poses
ICP_SOURCES = ("measured", "self-reported", "derived")


@dataclass(frozen=True)
class EpisodeScore:
    episode: Episode
    metrics: EpisodeMetrics
    missing: bool  # no prediction: scored as a failure
    icp_source: str  # where c(t) came from: one of ICP_SOURCES, "missing" without a prediction
    prediction: Prediction | None = field(default=None, compare=False)  # what the agent did (None: missing)
    intensity: np.ndarray | None = field(default=None, compare=False)  # [T] the c(t) scored (the pictures mark it)

    @property
    def replayed(self) -> bool:
        return self.icp_source == "derived"


def score_prediction(episode: Episode, prediction: Prediction, intensity: np.ndarray,
                     config: MetricConfig = MetricConfig(), *, on_foot: GoalField | None) -> EpisodeMetrics:
    """Metrics of one prediction; `intensity` [T] is the prediction's c(t) or the replayed one; `on_foot` the
    goal's distances on foot (None: straight distances, an open floor)."""
    return score_episode(np.asarray(prediction.poses, dtype=np.float64), episode.reference_path, episode.goal,
                         on_foot=on_foot, goal_radius=episode.goal_radius, geodesic_distance=episode.geodesic_distance,
                         stopped=prediction.stopped, collision_intensity=intensity, config=config)


def score_episodes(episodes: Sequence[Episode], matched: Mapping[str, Prediction], derived: Mapping[str, np.ndarray],
                   maps: Mapping[str, NavigableMap], config: MetricConfig = MetricConfig()) -> list[EpisodeScore]:
    """Every episode's score, distances on foot on its scene's map: without a prediction a failure, else with c(t)
    as the prediction's icp_source says (`derived`: evaluate's replay, by episode id)."""
    scores = []
    for e in episodes:
        p = matched.get(e.episode_id)
        if p is None:
            scores.append(EpisodeScore(e, missing_metrics(maps[e.scene_id].field(e.goal)), missing=True,
                                       icp_source="missing"))
            continue
        source = icp_source(p)
        c = derived[e.episode_id] if source == "derived" else np.asarray(p.collision_intensity, dtype=np.float64)
        scores.append(EpisodeScore(e, score_prediction(e, p, c, config, on_foot=maps[e.scene_id].field(e.goal)),
                                   missing=False, icp_source=source, prediction=p, intensity=c))
    return scores


def icp_source(prediction: Prediction) -> str:
    """One of ICP_SOURCES for a prediction."""
    if prediction.collision_intensity is None:
        return "derived"
    return "measured" if prediction.intensity_source == "simulator" else "self-reported"


def missing_metrics(on_foot: GoalField) -> EpisodeMetrics:
    """The worst value of every metric on the goal's map (module docstring)."""
    return EpisodeMetrics(ne=on_foot.worst, ne_straight=on_foot.worst_straight, sr=0.0, osr=0.0, spl=0.0, ndtw=0.0,
                          sdtw=0.0, csr=0.0, icp=1.0, ps=0.0, path_length=0.0)


def mean_metrics(scores: Sequence[EpisodeScore]) -> dict[str, float]:
    """Plain means over the episodes of every metric, plus `episodes` (the count)."""
    table = np.array([[getattr(s.metrics, m) for m in METRIC_NAMES] for s in scores], dtype=np.float64)
    means = table.mean(axis=0) if len(scores) else np.full(len(METRIC_NAMES), np.nan)
    return {"episodes": len(scores), **{m: float(v) for m, v in zip(METRIC_NAMES, means)}}


@dataclass(frozen=True)
class Summary:
    """Means overall, per instruction level, per instruction type and per split (keys sorted)."""

    overall: dict[str, float]
    by_level: dict[str, dict[str, float]]
    by_type: dict[str, dict[str, float]]
    by_split: dict[str, dict[str, float]]


def summarise_scores(scores: Sequence[EpisodeScore]) -> Summary:
    def groups(key: str) -> dict[str, dict[str, float]]:
        names = sorted({getattr(s.episode, key) for s in scores})
        return {n: mean_metrics([s for s in scores if getattr(s.episode, key) == n]) for n in names}

    return Summary(overall=mean_metrics(scores), by_level=groups("level"), by_type=groups("type"),
                   by_split=groups("split"))
