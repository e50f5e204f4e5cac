"""sagebench's tasks in SAGE-3D's GVLN files: which file a task goes to, the sample fields SAGE-Bench's task classes
read (Code/benchmark/environment_evaluation/task_types.py), and the task a sample of a file holds.

SAGE-Bench runs one task per `run_benchmark.py --task-type` call over files its episodes_adapter.py reads the same
way for every task: start = the first point's position and rotation, goal = the last point, one episode per
instruction. So each task is written to files of its own (SAGE batched no-goal episodes with VLN ones and scored
them by the goal criterion: an agent that never moved succeeded). A no-goal sample is its start point alone, with
a "Goal-less" instruction and task_type "no_goal_exploration" (what its infer_task_type looks for); a goal task's
sample is its reference path, plus the fields its task class names: target_object and target_object_position
(ObjectNav), goal_position (PointNav), target_image and target_image_position (ImgNav), in SAGE's 3D frame.
"""

from __future__ import annotations

from typing import Any

from sagebench.gvln.frame import SAGE_Z, to_sage_xy

# sagebench's task -> SAGE-Bench's --task-type
SAGE_TASK_TYPE = {"vln": "vln", "nogoal": "nogoalnav", "objectnav": "objectnav", "pointnav": "pointnav",
                  "imagenav": "imgnav"}
GOAL_LESS = "Goal-less"  # SAGE-3D's instruction type of its no-goal instructions
NO_GOAL_SAMPLE = "no_goal_exploration"  # SAGE-Bench's episode task_type of a no-goal episode
# the task columns a sample's "sagebench" entry keeps, world frame
TASK_KEYS = ("task", "budget_s", "budget_steps", "goal_category", "goal_instance_ids", "goal_viewpoints",
             "goal_polar", "goal_yaw", "goal_image")


def sage_position(position: list[float], floor: float, offset: tuple[float, float]) -> list[float]:
    """A world point as SAGE-3D writes trajectory points: its 3D frame (`offset`: the scene's), SAGE_Z above the
    floor."""
    x, y = to_sage_xy(position[:2], offset)
    return [float(x), float(y), floor + SAGE_Z]


def sage_task_fields(row: dict[str, Any], floor: float, offset: tuple[float, float]) -> dict[str, Any]:
    """The sample fields SAGE-Bench's task class of the row's task reads (none for vln)."""
    task, goal = row.get("task") or "vln", sage_position(row["goal_position"], floor, offset)
    if task == "nogoal":
        return {"task_type": NO_GOAL_SAMPLE}
    if task == "objectnav":
        return {"target_object": row["goal_category"], "target_object_position": goal}
    if task == "pointnav":
        return {"goal_position": goal}
    if task == "imagenav":
        return {"target_image": row["goal_image"], "target_image_position": goal}
    return {}


def sample_task(given: str | None, fields: dict[str, Any], instruction_types: list[str]) -> str:
    """The task of a sample: its "sagebench" entry's, else the one SAGE-Bench's infer_task_type finds from the
    fields it names (`fields`: those the sample has), with one change: its task fields come before its
    instructions, which SAGE-3D writes for VLN samples only (a sample of Goal-less instructions alone is no-goal;
    a VLN sample's Goal-less instructions become no-goal episodes of their own)."""
    if given is not None:
        return given
    if fields.get("task_type") == NO_GOAL_SAMPLE or (instruction_types and set(instruction_types) == {GOAL_LESS}):
        return "nogoal"
    for key, task in (("target_object", "objectnav"), ("target_image", "imagenav"),
                      ("target_image_position", "imagenav"), ("goal_position", "pointnav")):
        if fields.get(key) is not None:
            return task
    return "vln"
