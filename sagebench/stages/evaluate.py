"""`evaluate`: score agent predictions (JSON Lines) against a run's episodes and aggregate the metrics.

Reads RUN/episodes/<id>/part-*.parquet and the predictions file; for predictions without collision_intensity
also RUN/scenes/<id>/scene.json and scene.xml (export-usd), whose colliders the poses are replayed against.
Writes the results JSON (when asked): means overall, per instruction level and per type, the metrics of every
episode, the ids of missing episodes and the settings; with --visualize, one picture per scored episode.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from sagebench import ui
from sagebench.episodes.episode import Episode
from sagebench.episodes.load import load_episodes
from sagebench.errors import ConfigError, DataError
from sagebench.evaluation.intensity import ICP_NOTE, derive_intensity
from sagebench.evaluation.pictures import write_pictures
from sagebench.evaluation.predictions import Prediction, check_on_map, match_episodes, read_predictions
from sagebench.evaluation.record import RolloutRecord, read_record, record_path
from sagebench.evaluation.scoring import (
    DISTANCE_USED, ICP_SOURCES, METRIC_NAMES, TASK_METRICS, EpisodeScore, Summary, TaskScoring, score_episodes,
    summarise_scores, within_budget,
)
from sagebench.fileio import write_json
from sagebench.input_files import read_regular
from sagebench.metrics import NavigableMap
from sagebench.run_folder import Output, claim_output_file
from sagebench.run_layout import SEMANTIC_MAP, TOPDOWN, run_scene_dir
from sagebench.settings.evaluate import EvaluateConfig
from sagebench.settings.shared import SPLITS
from sagebench.topdown.grid_file import read_topdown_grids
from sagebench.topdown.semantic_map import read_semantic_map

if TYPE_CHECKING:  # MuJoCo loads only for predictions without c(t), whose poses are replayed
    from sagebench.replay.physics import ReplayModel


# ---------------------------------------------------------------- inputs


def _check_start(episodes: dict[str, Episode], rows: list[tuple[int, Prediction]], path: Path,
                 tolerance: float) -> None:
    for n, p in rows:
        e = episodes[p.episode_id]
        off = float(np.hypot(p.poses[0][0] - e.start[0], p.poses[0][1] - e.start[1]))
        if off > tolerance:
            raise DataError(f"the first pose is {off:.3f} m from the episode's start_position (more than "
                            f"{tolerance} m)", path=f"{path}:{n}", field="poses[0]")


def _in_split(split: str, episodes: list[Episode], rows: list[tuple[int, Prediction]],
              run_dir: Path) -> tuple[list[Episode], list[tuple[int, Prediction]]]:
    """The episodes of `split`, and the predictions less those of the run's other episodes."""
    if split not in SPLITS:
        raise ConfigError(f"{split!r} is not a split (one of {', '.join(SPLITS)})", field="--split")
    others = {e.episode_id for e in episodes if e.split != split}
    episodes = [e for e in episodes if e.split == split]
    if not episodes:
        raise DataError(f"no episodes in split {split!r}", path=run_dir)
    return episodes, [(n, p) for n, p in rows if p.episode_id not in others]


# ---------------------------------------------------------------- evaluation


@dataclass(frozen=True)
class Evaluation:
    scores: list[EpisodeScore]
    summary: Summary
    missing: list[str]
    predictions: Path
    predictions_sha256: str
    config: EvaluateConfig
    split: str | None = None  # the split scored (evaluate --split), None for all
    record: RolloutRecord | None = None  # the rollout's record beside the predictions, when there is one
    asked_only: bool = False  # only the episodes the rollout was asked to run were scored
    tasks: TaskScoring = TaskScoring()  # how the episodes of tasks other than VLN were scored
    cut_at_budget: tuple[str, ...] = ()  # nogoal episodes whose prediction ran past the budget, scored up to it

    def to_json(self) -> dict:
        def rounded(d: dict[str, float]) -> dict[str, float]:
            return {k: (v if k == "episodes" else _r(v)) for k, v in d.items()}

        return {
            "predictions": {"file": self.predictions.name, "sha256": self.predictions_sha256},
            "episodes": len(self.scores),
            "missing": self.missing,
            "intensity_replayed": sum(s.replayed for s in self.scores),
            "icp_source": {k: sum(s.icp_source == k for s in self.scores) for k in ICP_SOURCES},
            "overall": rounded(self.summary.overall),
            "by_level": {k: rounded(v) for k, v in self.summary.by_level.items()},
            "by_type": {k: rounded(v) for k, v in self.summary.by_type.items()},
            "by_split": {k: rounded(v) for k, v in self.summary.by_split.items()},
            "split": self.split,
            "observations": self.record.observations.model_dump() if self.record else None,
            "rollout": None if self.record is None else {
                "asked": len(self.record.episodes), "scored_asked_only": self.asked_only,
                "complete": self.record.complete, "success_distance": self.record.success_distance,
                "failed_by_policy": [f.episode_id for f in self.record.failed_by_policy]},
            "per_episode": [self._episode_json(s) for s in self.scores],
            "distance_used": DISTANCE_USED,
            "config": self.config.model_dump(mode="json"),
            **({} if self.summary.tasks_only_vln else {
                "by_task": {k: rounded(v) for k, v in self.summary.by_task.items()},
                "task_metrics": asdict(self.tasks.config) | {"step_seconds": self.tasks.step_seconds},
                **({"cut_at_budget": len(self.cut_at_budget)} if "nogoal" in self.summary.by_task else {})}),
        }

    def _episode_json(self, s: EpisodeScore) -> dict:
        task = {} if self.summary.tasks_only_vln else {"task": s.episode.task}
        if s.episode.task == "nogoal":
            task["cut_at_budget"] = s.episode.episode_id in self.cut_at_budget
        return {"episode_id": s.episode.episode_id, "scene_id": s.episode.scene_id, **task,
                "instruction_level": s.episode.level, "instruction_type": s.episode.type, "split": s.episode.split,
                "missing": s.missing, "icp_source": s.icp_source,
                **{m: _r(getattr(s.metrics, m)) for m in TASK_METRICS[s.episode.task]}}

    def table(self) -> str:
        """The means as a fixed-width text table: VLN's overall, then per level, type and split (left out when the
        run scored no VLN episode), then one group per task when there are tasks other than VLN."""
        cols = ("episodes", *METRIC_NAMES)
        label = {"path_length": "LEN", "ne_straight": "NE_STR"}
        head = f"{'group':<32}" + "".join(f"{label.get(c, c.upper()):>9}" for c in cols)
        lines = [head] if self.summary.overall["episodes"] or self.summary.tasks_only_vln else []
        groups = [("overall", self.summary.overall)] if lines else []
        groups += [(f"level {k}", v) for k, v in self.summary.by_level.items()]
        groups += [(f"type {k}", v) for k, v in self.summary.by_type.items()]
        groups += [(f"split {k}", v) for k, v in self.summary.by_split.items()]
        for name, d in groups:
            lines.append(f"{name:<32}" + f"{d['episodes']:>9d}" + "".join(f"{d[m]:>9.3f}" for m in METRIC_NAMES))
        if not self.summary.tasks_only_vln:
            lines += self._task_lines(label)
        used: dict[str, list[str]] = {}
        for m, how in DISTANCE_USED.items():
            used.setdefault(how.split()[0], []).append(label.get(m, m.upper()))
        lines.append("distance to the goal: " + "; ".join(f"{how.replace('_', ' ')} for {', '.join(ms)}"
                                                         for how, ms in used.items()))
        counts = {k: sum(s.icp_source == k for s in self.scores) for k in ICP_SOURCES}
        lines.append("ICP from c(t) " + ", ".join(f"{k} in {n} episodes" for k, n in counts.items() if n)
                     + f" ({ICP_NOTE})")
        lines.append(self.observed())
        return "\n".join(lines)

    def _task_lines(self, label: dict[str, str]) -> list[str]:
        """One group per task, each with its own metrics (the groups above are VLN's)."""
        lines, label = [], label | {"collisions": "HITS", "time": "TIME_S"}
        for task, d in self.summary.by_task.items():
            names = TASK_METRICS[task]
            lines.append(f"{'task ' + task:<32}{'episodes':>9}" + "".join(f"{label.get(m, m.upper()):>9}" for m in names))
            lines.append(f"{'':<32}{d['episodes']:>9d}" + "".join(f"{d[m]:>9.3f}" for m in names))
            if task == "nogoal":
                lines.append(f"nogoal: {len(self.cut_at_budget)} of {d['episodes']} episodes ran past their budget "
                             "and were scored up to it (the simulator ends them there)")
        c = self.tasks.config
        lines.append(f"objectnav succeeds within {c.viewpoint_tolerance:g} m of a goal viewpoint on foot; nogoal when "
                     f"coverage >= {c.coverage_success:g} with no collision (COVERAGE: the main region's navigable "
                     f"floor within the agent's radius of its path)")
        return lines

    def observed(self) -> str:
        """What the agent observed, from the rollout's record (one line, or more when it is incomplete)."""
        r = self.record
        if r is None:
            return "observations: not recorded (predictions without a rollout record)"
        out = [f"observations ({r.observations.line()})"]
        scored = "exactly the" if self.asked_only else "every episode, not only the"
        out.append(f"scored {scored} {len(r.episodes)} episodes the rollout was asked to run"
                   + (f"; success within {r.success_distance:g} m" if r.success_distance is not None else ""))
        if r.failed_by_policy:
            out.append(f"{len(r.failed_by_policy)} episodes failed by the policy (scored as missing): "
                       + ", ".join(f.episode_id for f in r.failed_by_policy[:5])
                       + (", ..." if len(r.failed_by_policy) > 5 else ""))
        if not r.complete:
            out.append("the rollout is incomplete: sagebench rollout --resume runs the rest")
        return "\n".join(out)


def read_navigable_map(run_dir: Path, scene_id: str) -> NavigableMap:
    """The scene's navigable map, for distances on foot (a final pose off it snaps back within the radius of the
    agent the map was built for)."""
    scene_dir = run_scene_dir(run_dir, scene_id)
    grids = read_topdown_grids(scene_dir / TOPDOWN)
    radius = read_semantic_map(scene_dir / SEMANTIC_MAP).agent().radius
    return NavigableMap(grids.navigable, grids.resolution, grids.origin, snap_radius=radius)


def _r(x: float) -> float | None:
    return round(float(x), 6) if np.isfinite(x) else None


def _replay_models(run_dir: Path, scene_ids: list[str], config: EvaluateConfig) -> dict[str, ReplayModel]:
    """The replay model of each scene whose poses are replayed (MuJoCo is imported only then)."""
    if not scene_ids:
        return {}
    from sagebench.replay.scene_model import open_replay_model

    return {sid: open_replay_model(run_dir, sid, replay=config.replay) for sid in scene_ids}


def _derived(models: dict[str, ReplayModel], episodes: list[Episode], matched: dict[str, Prediction],
             workers: int) -> dict[str, np.ndarray]:
    """Evaluate's c(t) [T] by episode id for the predictions without one, replayed in their scene's model."""
    derived: dict[str, np.ndarray] = {}
    for sid in ui.track(list(models), "replaying poses"):
        ids = [e.episode_id for e in episodes if e.scene_id == sid and e.episode_id in matched
               and matched[e.episode_id].collision_intensity is None]
        derived.update(zip(ids, derive_intensity(models[sid], [np.asarray(matched[i].poses) for i in ids],
                                                 threads=workers)))
    return derived


def is_evaluation(path: Path) -> bool:
    """Whether `path` holds results evaluate wrote: a JSON object with its keys."""
    try:
        doc = json.loads(read_regular(path, limit=1 << 30) or b"")
    except (ValueError, RecursionError):
        return False
    return isinstance(doc, dict) and {"predictions", "overall", "per_episode", "distance_used"} <= doc.keys()


def evaluate(run_dir: Path, predictions: Path, config: EvaluateConfig = EvaluateConfig(), *,
             scene_id: str | None = None, split: str | None = None, out: Path | None = None,
             force: bool = False) -> Evaluation:
    """Score `predictions` against the run's episodes (or `scene_id`'s, or `split`'s: predictions of the run's
    other episodes are then left out); write `out` (JSON) when given, claimed first (run_folder.claim_output_file:
    never over a file sagebench did not write unless `force`, never over the predictions or their record).

    Every check (format, ids, starts, inputs) passes before anything is replayed or written.
    """
    run_dir, predictions = Path(run_dir), Path(predictions)
    if out is None:
        return _scored(run_dir, predictions, config, scene_id, split)
    with claim_output_file(Output(Path(out), is_evaluation), "evaluate", force=force,
                           inputs={"--predictions": predictions, "their rollout record": record_path(predictions)}):
        result = _scored(run_dir, predictions, config, scene_id, split)
        write_json(Path(out), result.to_json())
        return result


def _scored(run_dir: Path, predictions: Path, config: EvaluateConfig, scene_id: str | None,
            split: str | None) -> Evaluation:
    episodes = load_episodes(run_dir, scene_id)
    rows = read_predictions(predictions, allow_empty=True)
    record = read_record(predictions)
    asked_only = record is not None and not config.all_episodes
    if record is not None:
        if record.success_distance is not None:
            episodes = [replace(e, goal_radius=record.success_distance) for e in episodes]
        if asked_only:
            wanted = set(record.episodes)
            episodes = [e for e in episodes if e.episode_id in wanted]
            if not episodes:
                raise DataError("none of the episodes the rollout was asked to run is in this run (or --scene)",
                                path=record_path(predictions))
    elif not rows:
        raise DataError("no predictions (the file is empty)", path=predictions)
    if split is not None:
        episodes, rows = _in_split(split, episodes, rows, run_dir)
    by_id = {e.episode_id: e for e in episodes}
    matched, missing = match_episodes(rows, by_id, predictions, allow_missing=config.allow_missing or asked_only)
    _check_start(by_id, rows, predictions, config.start_tolerance)
    need_replay = sorted({by_id[p.episode_id].scene_id for p in matched.values() if p.collision_intensity is None})
    maps = {sid: read_navigable_map(run_dir, sid) for sid in sorted({e.scene_id for e in episodes})}
    check_on_map(rows, lambda eid: maps[by_id[eid].scene_id].bounds, predictions)
    models = _replay_models(run_dir, need_replay, config)
    tasks = task_scoring(record)
    scored = {i: within_budget(by_id[i], p, tasks.step_seconds) for i, p in matched.items()}
    scores = score_episodes(episodes, scored, _derived(models, episodes, scored, config.workers), maps, config.metrics,
                            tasks)
    return Evaluation(scores=scores, summary=summarise_scores(scores), missing=missing, predictions=predictions,
                      predictions_sha256=hashlib.sha256(predictions.read_bytes()).hexdigest(), config=config,
                      split=split, record=record, asked_only=asked_only, tasks=tasks,
                      cut_at_budget=tuple(sorted(i for i in scored if scored[i] is not matched[i])))


def task_scoring(record: RolloutRecord | None) -> TaskScoring:
    """The other tasks' scoring: a step lasts the rollout's control interval (its record's), else the default's."""
    interval = ((record.settings.get("env") or {}).get("actions") or {}).get("control_interval") if record else None
    return TaskScoring() if interval is None else TaskScoring(step_seconds=float(interval))


def draw_pictures(run_dir: Path, result: Evaluation, out_dir: Path) -> list[Path]:
    """evaluate --visualize: one picture of every scored episode into `out_dir`, on its scene's map."""
    scenes = sorted({s.episode.scene_id for s in result.scores})
    grids = {sid: read_topdown_grids(run_scene_dir(run_dir, sid) / TOPDOWN) for sid in scenes}
    drawn = {"file": result.predictions.name, "sha256": result.predictions_sha256}
    return write_pictures(result.scores, grids, out_dir, drawn)
