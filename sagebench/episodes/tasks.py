"""The tasks' episode contract (docs/tasks.md): the columns each task fills, the shards' schema once a task other
than vln is written, the check of a row against its task, and the point goal as habitat's sensor gives it.

A run of vln alone writes EPISODE_SCHEMA, byte for byte as before tasks existed: a shard without a `task` column
holds vln rows. A run with any other task writes TASK_SCHEMA for every row, vln rows included: EPISODE_SCHEMA, then
`task` and the task columns, null where a row's task does not use them, so all shards of such a run share one
schema. Every task fills the shared columns: start pose; goal_position, goal_radius and geodesic_distance (the
success geometry, except nogoal, which has no goal: its goal is its start, radius 0, distance 0, and its success is
never a distance test); reference_path (a shortest path to the goal; nogoal: the start alone).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path

import pyarrow as pa
import pyarrow.compute as pc

from sagebench.episodes.schema import EPISODE_FIELDS, EPISODE_SCHEMA
from sagebench.errors import DataError
from sagebench.settings.shared import TASKS

_F64 = pa.float64()
VLN = "vln"
NOGOAL = "nogoal"
# SAGE-Bench's no-goal instruction (task_types.py NoGoalNavTask), word for word
NOGOAL_INSTRUCTION = ("Explore this environment as much as possible, but avoid colliding with objects, walls, etc., "
                      "and maintain safe navigation.")

TASK_FIELDS: list[tuple[pa.Field, str]] = [
    (pa.field("task", pa.string(), nullable=False),
     "vln, nogoal, objectnav, pointnav or imagenav: what the agent is given and how it is scored (docs/tasks.md)."),
    (pa.field("budget_s", _F64), "nogoal: time budget, s (SAGE-Bench: 80)."),
    (pa.field("budget_steps", pa.int32()), "nogoal: step budget, actions."),
    (pa.field("goal_category", pa.string()), "objectnav: the goal category; any instance of it counts."),
    (pa.field("goal_instance_ids", pa.list_(pa.int32())), "objectnav: instance ids of every instance of the category."),
    (pa.field("goal_viewpoints", pa.list_(pa.list_(_F64, 3))),
     "objectnav: [x, y, z] centres of the main region's navigable cells within goal_radius of any instance's "
     "footprint; goal_position is the nearest of them by geodesic distance."),
    (pa.field("goal_polar", pa.list_(_F64, 2)),
     "pointnav: [rho, phi] of the goal from the start pose, habitat's PointGoalWithGPSCompassSensor (POLAR, 2-D): "
     "rho metres in the floor plane, phi radians counter-clockwise from the start heading."),
    (pa.field("goal_yaw", _F64), "imagenav: heading of the goal camera, radians CCW from +X."),
    (pa.field("goal_image", pa.string()),
     "imagenav: the goal image: 'render:' + the goal pose x,y,yaw, rendered on demand from the scene's Gaussians by "
     "the rollout's own renderer and camera (--renderer; auto picks gsplat where it can run), or the path of a PNG "
     "file relative to the run, which is the image shown (docs/tasks/imagenav.md)."),
]

TASK_SCHEMA = pa.schema([f.with_metadata({"description": doc}) for f, doc in EPISODE_FIELDS + TASK_FIELDS],
                        metadata=EPISODE_SCHEMA.metadata)

# the task columns each task needs non-null (the shared columns are non-null for every task)
REQUIRED: dict[str, tuple[str, ...]] = {
    "vln": (),
    "nogoal": ("budget_s", "budget_steps", "instruction_text"),
    "objectnav": ("goal_category", "goal_instance_ids", "goal_viewpoints"),
    "pointnav": ("goal_polar",),
    "imagenav": ("goal_yaw", "goal_image"),
}


def schema_for(tasks: Iterable[str]) -> pa.Schema:
    """The shards' schema for a run of `tasks`: EPISODE_SCHEMA for vln alone, else TASK_SCHEMA."""
    return EPISODE_SCHEMA if set(tasks) <= {VLN} else TASK_SCHEMA


def task_field_descriptions() -> dict[str, str]:
    """Task column name -> meaning, in column order."""
    return {f.name: doc for f, doc in TASK_FIELDS}


def row_task(row: dict) -> str:
    """The task of a row read back (a shard without a `task` column holds vln rows)."""
    return row.get("task") or VLN


def check_task_table(table: pa.Table, where: Path) -> None:
    """A DataError naming `where` and the field at the first row whose task is unknown or that lacks a column its
    task needs (null, or an empty list); a table without a `task` column holds vln rows and passes."""
    if "task" not in table.column_names:
        return
    tasks = pc.fill_null(table.column("task"), VLN)  # a vln-only shard read with a task run's schema
    unknown = pc.invert(pc.is_in(tasks, pa.array(TASKS)))
    if pc.any(unknown).as_py():
        i = pc.index(unknown, True).as_py()
        raise DataError(f"episode {table.column('episode_id')[i].as_py()}: task {tasks[i].as_py()!r} is not one of "
                        f"{', '.join(TASKS)}", path=where, field="task")
    for task, names in REQUIRED.items():
        for name in names:
            col = table.column(name) if name in table.column_names else pa.nulls(table.num_rows)
            empty = pc.is_null(col)
            if pa.types.is_list(col.type):
                empty = pc.or_(empty, pc.equal(pc.fill_null(pc.list_value_length(col), 0), 0))
            bad = pc.and_(pc.equal(tasks, task), empty)
            if pc.any(bad).as_py():
                i = pc.index(bad, True).as_py()
                raise DataError(f"episode {table.column('episode_id')[i].as_py()}: a {task} episode needs {name}",
                                path=where, field=name)


def pointgoal_polar(x: float, y: float, yaw: float, goal_x: float, goal_y: float) -> tuple[float, float]:
    """[rho, phi] of the goal seen from pose (x, y, yaw), as habitat's PointGoalWithGPSCompassSensor (POLAR, 2-D)
    reports it: rho the floor-plane distance, phi the angle counter-clockwise (to the left) from the heading, in
    (-pi, pi]. (habitat's agent frame is -Z forward, +X right, Y up; its sensor returns [rho, -atan2(right, forward)],
    which is this phi.)"""
    dx, dy = goal_x - x, goal_y - y
    forward = dx * math.cos(yaw) + dy * math.sin(yaw)
    left = -dx * math.sin(yaw) + dy * math.cos(yaw)
    return math.hypot(dx, dy), math.atan2(left, forward)


def goal_image_recipe(x: float, y: float, yaw: float) -> str:
    """The goal_image value of an imagenav episode whose goal camera stands at (x, y) looking along yaw."""
    return f"render:{x!r},{y!r},{yaw!r}"
