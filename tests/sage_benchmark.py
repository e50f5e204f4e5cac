"""SAGE-Bench's reading of a GVLN trajectory file, re-implemented for the tests from the behaviour of SAGE-3D's
Code/benchmark/environment_evaluation/ (episodes_adapter.py, task_types.py, measures.py, run_benchmark.py,
simple_env.py): not copied and not imported.

run_benchmark.py reads every task's file with the same adapter (one episode per instruction,
"<trajectory_id>-<k>", start = the first point's position and rotation, goal = the last point), then
adapt_episode_for_task for its --task-type; the start pose it sets is the adapter's, and every measure but the
no-goal ones scores against goals[0] (the last point). What the task classes give the agent: VLN the
instruction, ObjectNav "Find the <object>" (the object found by keyword in the instruction, else "unknown"),
PointNav the goal coordinates, ImgNav a fixed sentence, NoGoalNav the exploration sentence.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

TASK_TYPES = ("vln", "objectnav", "pointnav", "imgnav", "nogoalnav")
EXPLORE = ("Explore this environment as much as possible, but avoid colliding with objects, walls, etc., and "
           "maintain safe navigation.")
OBJECT_KEYWORDS = (("folder", "folder"), ("window", "window"), ("chair", "chair"), ("screen", "projection_screen"))


def sage_adapter(path: Path) -> list[dict]:
    """SAGE-3D's episodes as its benchmark builds them from a GVLN file."""
    data = json.loads(path.read_text())
    scene = data["scenes"][0]
    episodes = []
    for sample in scene.get("samples", []):
        points = sample["points"]
        assert points, "Sample has no points"
        instructions = sample.get("instructions", [""])
        if not instructions:
            parsed = [(0, "", "", "", "")]
        elif isinstance(instructions[0], str):
            parsed = [(i, t, "", "", "") for i, t in enumerate(instructions)]
        else:
            parsed = [(i, d.get("generated_instruction", ""), d.get("instruction_type", ""), d.get("start", ""),
                       d.get("end", "")) for i, d in enumerate(instructions) if isinstance(d, dict)]
        for k, text, kind, start, end in parsed:
            episodes.append({"episode_id": f"{sample.get('trajectory_id', '0')}-{k}", "instruction": text,
                             "instruction_type": kind, "start_item": start, "end_item": end,
                             "start_position": points[0]["position"], "start_rotation": points[0]["rotation"],
                             "goal": points[-1]["position"], "scene_name": scene.get("scene_name", "scene")})
    return episodes


def told(episode: dict, task_type: str) -> str:
    """What SAGE's task class of `task_type` tells the agent for an adapter episode."""
    if task_type == "vln":
        return episode["instruction"]
    if task_type == "objectnav":
        text = episode["instruction"].lower()
        return "Find the " + next((name for key, name in OBJECT_KEYWORDS if key in text), "unknown")
    if task_type == "pointnav":
        return "Navigate to coordinates (0.00, 0.00, 0.00)"  # its goal_position is never set from the adapter
    if task_type == "imgnav":
        return "Navigate to the location that matches the target image"
    return EXPLORE


def run_benchmark(path: Path, task_type: str) -> list[dict]:
    """The episodes `run_benchmark.py --task-type task_type` runs from the GVLN file `path`, each with what
    the agent is told ("told") and what it is scored against ("goal": None for the no-goal task)."""
    assert task_type in TASK_TYPES
    return [{**e, "told": told(e, task_type), "goal": None if task_type == "nogoalnav" else e["goal"]}
            for e in sage_adapter(path)]


def sage_heading(rotation: list[float]) -> float:
    """The heading SAGE-3D's simulator starts an episode with, in its 3D frame."""
    qx, _, _, qw = rotation
    return math.remainder(2 * math.atan2(-qx, qw) - math.pi, 2 * math.pi)
