"""Reading a run's episodes: the rows for scoring, the trajectories for replay."""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa

from sagebench.errors import DataError
from sagebench.episodes.episode import NO_LEVEL, Episode
from sagebench.episodes.tasks import VLN, row_task, task_field_descriptions
from sagebench.run_layout import run_episodes_dir, run_scenes


@dataclass(frozen=True)
class Trajectory:
    """One trajectory of the episodes table (its rows share path and goal)."""

    trajectory_id: str
    episode_ids: tuple[str, ...]
    reference_path: np.ndarray  # [M, 4] x, y, z, yaw
    goal: np.ndarray  # [3]
    goal_radius: float
    geodesic_distance: float
    base_action: tuple[str, ...] = ()  # the trajectory's Base_Action sentences
    task: str = VLN  # nogoal's path is its start alone (docs/tasks.md)


def read_trajectories(episodes_dir: Path) -> list[Trajectory]:
    """The episodes table grouped by trajectory_id (sorted), with the episode ids of each."""
    from sagebench.episodes.shards import read_episodes

    try:
        table = read_episodes(episodes_dir)
    except (OSError, pa.ArrowException) as err:
        raise DataError(f"cannot read episode shards: {err}", path=episodes_dir) from None
    rows: dict[str, list[dict]] = {}
    for row in table.select(["episode_id", "trajectory_id", "reference_path", "goal_position", "goal_radius",
                             "geodesic_distance", "instruction_type", "instruction_text",
                             *(["task"] if "task" in table.column_names else [])]).to_pylist():
        rows.setdefault(row["trajectory_id"], []).append(row)
    out = []
    for tid in sorted(rows):
        first = rows[tid][0]
        path = np.asarray(first["reference_path"], dtype=np.float64).reshape(-1, 4)
        if len(path) == 0:
            raise DataError(f"trajectory {tid}: empty path", path=episodes_dir, field="reference_path")
        out.append(Trajectory(tid, tuple(sorted(r["episode_id"] for r in rows[tid])), path,
                              np.asarray(first["goal_position"], dtype=np.float64), float(first["goal_radius"]),
                              float(first["geodesic_distance"]),
                              tuple(r["instruction_text"] for r in rows[tid] if r["instruction_type"] == "Base_Action"),
                              row_task(first)))
    return out


def load_episodes(run_dir: Path, scene_id: str | None = None, tasks: Collection[str] | None = None) -> list[Episode]:
    """Every episode row of the run (or of `scene_id`; of `tasks` only when given), in scene then file order (split
    "none" for shards written before the split column, task "vln" for shards without a task column)."""
    from sagebench.episodes.shards import read_episodes

    out = []
    for sid in run_scenes(run_dir, scene_id, having="episodes"):
        episodes_dir = run_episodes_dir(run_dir, sid)
        try:
            table = read_episodes(episodes_dir)
        except (OSError, pa.ArrowException) as err:
            raise DataError(f"cannot read episode shards: {err}", path=episodes_dir) from None
        columns = ["episode_id", "scene_id", "instruction_level", "instruction_type", "start_position", "start_yaw",
                   "goal_position", "goal_radius", "geodesic_distance", "reference_path", "instruction_text",
                   *(c for c in ("split", *task_field_descriptions()) if c in table.column_names)]
        for row in table.select(columns).to_pylist():
            if tasks is None or row_task(row) in tasks:
                out.append(episode_from_row(row, episodes_dir))
    return out


def episode_from_row(row: dict, where: Path) -> Episode:
    """An episode row (Parquet columns as a dict) as an Episode; an empty path is a DataError at `where`."""
    path = np.asarray(row["reference_path"], dtype=np.float64).reshape(-1, 4)
    if len(path) == 0:
        raise DataError(f"episode {row['episode_id']}: empty path", path=where, field="reference_path")
    return Episode(
        episode_id=row["episode_id"], scene_id=row["scene_id"],
        level=row["instruction_level"] or NO_LEVEL, type=row["instruction_type"] or NO_LEVEL,
        start=np.asarray(row["start_position"], dtype=np.float64), start_yaw=float(row["start_yaw"]),
        goal=np.asarray(row["goal_position"], dtype=np.float64), goal_radius=float(row["goal_radius"]),
        geodesic_distance=float(row["geodesic_distance"]), reference_path=path,
        split=row.get("split") or NO_LEVEL, instruction=row.get("instruction_text") or "", **task_goal(row))


def task_goal(row: dict) -> dict:
    """The Episode fields of the row's task (none for a row of a shard without task columns)."""
    viewpoints = row.get("goal_viewpoints")
    polar = row.get("goal_polar")
    return {"task": row_task(row), "budget_s": row.get("budget_s"), "budget_steps": row.get("budget_steps"),
            "goal_category": row.get("goal_category"), "goal_instance_ids": tuple(row.get("goal_instance_ids") or ()),
            "goal_viewpoints": None if viewpoints is None else np.asarray(viewpoints, dtype=np.float64).reshape(-1, 3),
            "goal_polar": None if polar is None else (float(polar[0]), float(polar[1])),
            "goal_yaw": row.get("goal_yaw"), "goal_image": row.get("goal_image")}
