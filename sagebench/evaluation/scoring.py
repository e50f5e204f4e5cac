"""Score predictions against episodes and aggregate: overall, per instruction level and per type, plain means.

Each episode is scored by its own task's metrics alone (TASK_METRICS; sagebench/tasks/goals.py): VLN's as ever,
the goal tasks' SR/OSR/SPL/NE/CSR/ICP/PS, no-goal's coverage, collisions, ICP, PS, path length and time. No
episode's score depends on the other episodes, of its task or another, scored with it. The overall, level, type and
split groups are VLN's; every task also gets a group of its own (`by_task`).

An episode without a prediction (evaluate --allow-missing) counts as a failure at every metric's worst value:
SR, OSR, SPL, nDTW, SDTW, CSR and PS 0, ICP 1, path length 0 and NE the largest distance on foot from the goal to
any navigable cell (NE_STRAIGHT the largest straight distance to one), so a missing prediction can only lower a score;
a no-goal episode's coverage, collisions and time are 0.

A no-goal prediction is scored only up to its episode's budget (`within_budget`), the one sagebench's simulator
ends the episode at: an agent run elsewhere cannot cover more, or take longer, by running past it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from sagebench.episodes.episode import Episode
from sagebench.evaluation.predictions import Prediction
from sagebench.metrics import EpisodeMetrics, NavigableMap, score_episode
from sagebench.metrics.exploration import ExplorationMetrics, score_exploration
from sagebench.metrics.goal import GoalMetrics, score_goal
from sagebench.metrics.on_foot import GoalField
from sagebench.settings.shared import ActionConfig, MetricConfig, TaskMetricConfig
from sagebench.tasks.budget import step_budget
from sagebench.tasks.goals import GOAL_TASKS, goal_field, success_distance

METRIC_NAMES = ("sr", "osr", "spl", "ne", "ne_straight", "ndtw", "sdtw", "csr", "icp", "ps", "path_length")
GOAL_METRICS = ("sr", "osr", "spl", "ne", "csr", "icp", "ps", "path_length")
NOGOAL_METRICS = ("sr", "coverage", "collisions", "icp", "ps", "path_length", "time")
TASK_METRICS = {"vln": METRIC_NAMES, "nogoal": NOGOAL_METRICS, **{t: GOAL_METRICS for t in GOAL_TASKS}}
Metrics = EpisodeMetrics | GoalMetrics | ExplorationMetrics
# which distance to the goal each metric stands on (evaluate reports this with the scores)
DISTANCE_USED = {"sr": "on_foot", "osr": "on_foot", "spl": "on_foot (success)", "ne": "on_foot",
                 "ne_straight": "straight", "sdtw": "on_foot (success)"}
# who measured an episode's c(t): sagebench rollout's simulator, the agent itself, or evaluate's replay of the poses
ICP_SOURCES = ("measured", "self-reported", "derived")


@dataclass(frozen=True)
class EpisodeScore:
    episode: Episode
    metrics: Metrics  # the episode's task's (TASK_METRICS)
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


@dataclass(frozen=True)
class TaskScoring:
    """What scores the episodes of tasks other than VLN: their constants and the control interval (a step's time)."""

    config: TaskMetricConfig = TaskMetricConfig()
    step_seconds: float = ActionConfig().control_interval


def within_budget(episode: Episode, prediction: Prediction, step_seconds: float) -> Prediction:
    """The prediction as the simulator would have ended it: a nogoal episode's first budget + 1 poses (and their
    c(t)), not stopped (the budget ended it), when it has more; any other prediction as it is."""
    budget = step_budget(episode, step_seconds)
    if budget is None or len(prediction.poses) <= budget + 1:
        return prediction
    c = prediction.collision_intensity
    return prediction.model_copy(update={"poses": prediction.poses[:budget + 1], "stopped": False,
                                         "collision_intensity": None if c is None else c[:budget + 1]})


def score_task(episode: Episode, prediction: Prediction, intensity: np.ndarray, navmap: NavigableMap,
               config: MetricConfig = MetricConfig(), tasks: TaskScoring = TaskScoring()) -> Metrics:
    """Metrics of one prediction by its episode's task (module docstring)."""
    poses = np.asarray(prediction.poses, dtype=np.float64)
    if episode.task == "vln":
        return score_prediction(episode, prediction, intensity, config, on_foot=navmap.field(episode.goal))
    if episode.task == "nogoal":
        return score_exploration(poses, navmap.main_region, navmap.resolution, navmap.origin,
                                 radius=navmap.snap_radius, min_coverage=tasks.config.coverage_success,
                                 step_seconds=tasks.step_seconds, collision_intensity=intensity)
    return score_goal(poses, goal_field(navmap, episode), goal_radius=success_distance(episode, tasks.config),
                      stopped=prediction.stopped, reference_path=episode.reference_path,
                      collision_intensity=intensity, config=config)


def score_episodes(episodes: Sequence[Episode], matched: Mapping[str, Prediction], derived: Mapping[str, np.ndarray],
                   maps: Mapping[str, NavigableMap], config: MetricConfig = MetricConfig(),
                   tasks: TaskScoring = TaskScoring()) -> list[EpisodeScore]:
    """Every episode's score, distances on foot on its scene's map: without a prediction a failure, else with c(t)
    as the prediction's icp_source says (`derived`: evaluate's replay, by episode id)."""
    scores = []
    for e in episodes:
        p = matched.get(e.episode_id)
        if p is None:
            scores.append(EpisodeScore(e, missing_task_metrics(e, maps[e.scene_id]), missing=True, icp_source="missing"))
            continue
        source = icp_source(p)
        c = derived[e.episode_id] if source == "derived" else np.asarray(p.collision_intensity, dtype=np.float64)
        scores.append(EpisodeScore(e, score_task(e, p, c, maps[e.scene_id], config, tasks),
                                   missing=False, icp_source=source, prediction=p, intensity=c))
    return scores


def icp_source(prediction: Prediction) -> str:
    """One of ICP_SOURCES for a prediction."""
    if prediction.collision_intensity is None:
        return "derived"
    return "measured" if prediction.intensity_source == "simulator" else "self-reported"


def missing_task_metrics(episode: Episode, navmap: NavigableMap) -> Metrics:
    """The worst value of every metric of the episode's task on its map (module docstring)."""
    if episode.task == "nogoal":
        return ExplorationMetrics(sr=0.0, coverage=0.0, collisions=0.0, icp=1.0, ps=0.0, path_length=0.0, time=0.0)
    if episode.task != "vln":
        return GoalMetrics(sr=0.0, osr=0.0, spl=0.0, ne=goal_field(navmap, episode).worst, csr=0.0, icp=1.0, ps=0.0,
                           path_length=0.0)
    return missing_metrics(navmap.field(episode.goal))


def missing_metrics(on_foot: GoalField) -> EpisodeMetrics:
    """The worst value of every VLN metric on the goal's map (module docstring)."""
    return EpisodeMetrics(ne=on_foot.worst, ne_straight=on_foot.worst_straight, sr=0.0, osr=0.0, spl=0.0, ndtw=0.0,
                          sdtw=0.0, csr=0.0, icp=1.0, ps=0.0, path_length=0.0)


def mean_metrics(scores: Sequence[EpisodeScore], names: Sequence[str] = METRIC_NAMES) -> dict[str, float]:
    """Plain means over the episodes of every metric named, plus `episodes` (the count)."""
    table = np.array([[getattr(s.metrics, m) for m in names] for s in scores], dtype=np.float64)
    means = table.mean(axis=0) if len(scores) else np.full(len(names), np.nan)
    return {"episodes": len(scores), **{m: float(v) for m, v in zip(names, means)}}


@dataclass(frozen=True)
class Summary:
    """VLN's means overall, per instruction level, per instruction type and per split (keys sorted), and each
    task's means by its own metrics (in TASK_METRICS' order)."""

    overall: dict[str, float]
    by_level: dict[str, dict[str, float]]
    by_type: dict[str, dict[str, float]]
    by_split: dict[str, dict[str, float]]
    by_task: dict[str, dict[str, float]] = field(default_factory=dict)

    @property
    def tasks_only_vln(self) -> bool:
        """Only VLN episodes were scored: the results read as they did before other tasks existed."""
        return set(self.by_task) <= {"vln"}


def summarise_scores(scores: Sequence[EpisodeScore]) -> Summary:
    vln = [s for s in scores if s.episode.task == "vln"]

    def groups(key: str) -> dict[str, dict[str, float]]:
        names = sorted({getattr(s.episode, key) for s in vln})
        return {n: mean_metrics([s for s in vln if getattr(s.episode, key) == n]) for n in names}

    present = {s.episode.task for s in scores}
    by_task = {t: mean_metrics([s for s in scores if s.episode.task == t], TASK_METRICS[t])
               for t in TASK_METRICS if t in present}
    return Summary(overall=mean_metrics(vln), by_level=groups("level"), by_type=groups("type"),
                   by_split=groups("split"), by_task=by_task)
