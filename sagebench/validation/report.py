"""What validate writes for one scene: the per-trajectory table (VALIDATION_SCHEMA) and report.json's content
(counts, failures by reason, metric distributions, alignment per frame, settings)."""

from __future__ import annotations

import io
from collections import Counter

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from sagebench.episodes.load import Trajectory
from sagebench.episodes.tasks import VLN
from sagebench.settings.validate import ValidateConfig
from sagebench.validation.checks import REASONS, START_ONLY, START_REASONS, Verdict
from sagebench.validation.frames import FrameCheck

METRICS = ("csr", "icp", "ps", "ndtw", "final_distance", "path_length", "max_penetration", "max_deviation", "steps")


def table_bytes(scene_id: str, trajectories: list[Trajectory], verdicts: list[Verdict]) -> bytes:
    """The per-trajectory table; a run with tasks other than vln adds each trajectory's `task` column."""
    tasks = _has_tasks(trajectories)
    rows = [{"scene_id": scene_id, **({"task": t.task} if tasks else {}), "trajectory_id": t.trajectory_id, "episode_ids": list(t.episode_ids),
             "passed": v.passed, "reasons": list(v.reasons), "reached_goal": v.reached_goal,
             "collision_free": v.collision_free, "final_distance": v.final_distance, "csr": v.csr, "icp": v.icp,
             "ps": v.ps, "ndtw": v.ndtw, "path_length": v.path_length, "reference_length": v.reference_length,
             "max_penetration": v.max_penetration, "max_deviation": v.max_deviation,
             "contact_steps": v.contact_steps, "steps": v.steps, "duration_s": v.duration, "outcome": v.outcome}
            for t, v in zip(trajectories, verdicts)]
    table = pa.Table.from_pylist(rows, schema=VALIDATION_TASK_SCHEMA if tasks else VALIDATION_SCHEMA)
    sink = io.BytesIO()
    pq.write_table(table, sink, compression="zstd", store_schema=True)
    return sink.getvalue()


VALIDATION_SCHEMA = pa.schema([
    ("scene_id", pa.string()), ("trajectory_id", pa.string()), ("episode_ids", pa.list_(pa.string())),
    ("passed", pa.bool_()), ("reasons", pa.list_(pa.string())), ("reached_goal", pa.bool_()),
    ("collision_free", pa.bool_()), ("final_distance", pa.float64()), ("csr", pa.float64()), ("icp", pa.float64()),
    ("ps", pa.float64()), ("ndtw", pa.float64()), ("path_length", pa.float64()), ("reference_length", pa.float64()),
    ("max_penetration", pa.float64()), ("max_deviation", pa.float64()), ("contact_steps", pa.int64()),
    ("steps", pa.int64()), ("duration_s", pa.float64()), ("outcome", pa.string()),
])
VALIDATION_TASK_SCHEMA = VALIDATION_SCHEMA.insert(1, pa.field("task", pa.string()))


def _has_tasks(trajectories: list[Trajectory]) -> bool:
    return any(t.task != VLN for t in trajectories)


def _distribution(values: np.ndarray) -> dict[str, float]:
    if not len(values):
        return {}
    q = np.percentile(values, [0, 5, 50, 95, 100])
    return {"mean": _r(values.mean()), "min": _r(q[0]), "p05": _r(q[1]), "p50": _r(q[2]), "p95": _r(q[3]),
            "max": _r(q[4])}


def _r(x: float) -> float | None:
    return round(float(x), 6) if np.isfinite(x) else None


def report(scene_id: str, trajectories: list[Trajectory], verdicts: list[Verdict], frames: list[FrameCheck],
            alignment_ok: bool, config: ValidateConfig) -> dict:
    """report.json's content; a run with tasks other than vln adds the trajectories per task, and its metric
    distributions are those of the replayed trajectories (a nogoal one's start alone is checked)."""
    failed = [(t, v) for t, v in zip(trajectories, verdicts) if v.reasons]
    reasons = REASONS + (START_REASONS if _has_tasks(trajectories) else ())
    replayed = [v for v in verdicts if v.outcome != START_ONLY]
    return {
        "scene_id": scene_id,
        **({"tasks": dict(sorted(Counter(t.task for t in trajectories).items()))} if _has_tasks(trajectories) else {}),
        "trajectories": len(trajectories),
        "episodes": sum(len(t.episode_ids) for t in trajectories),
        "passed": len(trajectories) - len(failed),
        "failed": len(failed),
        "failures_by_reason": {r: sum(r in v.reasons for _, v in failed) for r in reasons},
        "failures": [{"trajectory_id": t.trajectory_id, "episode_ids": list(t.episode_ids), "reasons": list(v.reasons)}
                     for t, v in failed],
        "metrics": {m: _distribution(np.array([getattr(v, m) for v in replayed], dtype=np.float64)) for m in METRICS},
        "alignment": {"ok": alignment_ok, "depth_tolerance": config.depth_tolerance,
                      "min_compared_fraction": config.min_compared_fraction,
                      "frames": [{"file": f.file, "trajectory_id": f.trajectory_id, "point": f.point,
                                  "median_abs_diff": _r(f.median_abs_diff), "compared_pixels": f.compared,
                                  "sampled_pixels": f.sampled, "problem": f.problem}
                                 for f in frames]},
        "config": config.model_dump(mode="json"),
    }
