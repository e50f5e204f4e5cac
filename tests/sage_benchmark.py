"""SAGE-Bench's reading of a GVLN trajectory file, re-implemented for the tests from the behaviour of SAGE-3D's
Code/benchmark/environment_evaluation/ (episodes_adapter.py, task_types.py, measures.py, run_benchmark.py,
simple_env.py, object_based_success.py) and of its semantic map (Code/data_pipeline/interiorgs_processing/
semantic_map_builder.py): not copied and not imported.

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

import cv2
import numpy as np
import shapely

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


# ---------------------------------------------------------------- SAGE-3D's 2D semantic map and its success test
# semantic_map_builder.py (Code/data_pipeline/interiorgs_processing/) and object_based_success.py, re-implemented.


def format2(value: float) -> str:
    return f"{float(value):.2f}"


def _item(label: str, cells: tuple[np.ndarray, np.ndarray], x0: float, y0: float, s: float, counters: dict) -> dict:
    """A semantic-map entry of mask cells (rows, cols) of the turned map: its box from the cells' edges."""
    ys, xs = cells
    counters[label] = counters.get(label, 0) + 1
    return {"category_label": label, "item_id": f"{label.strip().lower().replace(' ', '_')}_{counters[label]}",
            "bbox_m": [format2(x0 + xs.min() * s), format2(y0 + ys.min() * s), format2(x0 + (xs.max() + 1) * s),
                       format2(y0 + (ys.max() + 1) * s)],
            "mask_coords_m": [[format2(y0 + (y + 0.5) * s), format2(x0 + (x + 0.5) * s)] for y, x in zip(ys, xs)]}


def sage_semantic_map(labels: list[dict], png: np.ndarray, min_xy: tuple[float, float], scale: float) -> list[dict]:
    """The 2D semantic map semantic_map_builder.py makes of labels.json entries and occupancy.png's pixels (`png`,
    as read) on the grid at `min_xy`: labels' footprints at (H-1-i, W-1-j), then walls, then unable areas."""
    h, w = png.shape
    x0, y0 = min_xy
    out, counters = [], {}
    for obj in labels:
        poly = shapely.Polygon([[v["x"], v["y"]] for v in obj["bounding_box"][:4]])
        xy = np.array([[v["x"], v["y"]] for v in obj["bounding_box"][:4]])
        lo = [int(np.clip(np.floor((xy[:, a].min() - (x0, y0)[a]) / scale), 0, (w, h)[a] - 1)) for a in (0, 1)]
        hi = [int(np.clip(np.floor((xy[:, a].max() - (x0, y0)[a]) / scale), 0, (w, h)[a] - 1)) for a in (0, 1)]
        mask = np.zeros((h, w), dtype=bool)
        for j in range(lo[0], hi[0] + 1):
            for i in range(lo[1], hi[1] + 1):
                if poly.covers(shapely.Point(x0 + (j + 0.5) * scale, y0 + (i + 0.5) * scale)):
                    mask[h - 1 - i, w - 1 - j] = True
        if mask.any():
            out.append(_item(obj["label"], np.where(mask), x0, y0, scale, counters))
    values, counts = np.unique(png, return_counts=True)
    walls = [(c, v) for v, c in zip(values, counts) if 0 < v < 250]
    wall_value = min(walls, key=lambda cv: (-cv[0], cv[1]))[1] if walls else values[0]  # the first commonest
    for value, size in ((wall_value, 1), (0, 5)):
        n, blocks = cv2.connectedComponents(np.flipud(png == value).astype(np.uint8), connectivity=8)
        for k in range(1, n):
            if (blocks == k).sum() >= size:
                out.append(_item("wall" if size == 1 else "Unable Area", np.where(blocks == k), x0, y0, scale,
                                 counters))
    return out


def sage_to_2d(xy: list[float], smap: list[dict]) -> np.ndarray:
    """reverse_position_mapping: a 3D-frame point -> the 2D map's, about the rounded bounds of every mask cell."""
    ys = [float(y) for item in smap for y, _ in item["mask_coords_m"]]
    xs = [float(x) for item in smap for _, x in item["mask_coords_m"]]
    return np.array([min(xs) + max(xs) + xy[0], min(ys) + max(ys) + xy[1]])


def object_success(smap: list[dict], end: str, position: list[float], reach: float = 1.0) -> bool | None:
    """ObjectBasedSuccessEvaluator at the 3D-frame `position` for an episode whose first instruction ends at `end`:
    whether it stands in that item's box grown by `reach`; None when the map has no such item (the evaluator
    then guesses the target from the path's end)."""
    item = next((i for i in smap if i["item_id"] == end), None)
    if item is None:
        return None
    x0, y0, x1, y1 = (float(v) for v in item["bbox_m"])
    px, py = sage_to_2d(position, smap)
    return bool(x0 - reach <= px <= x1 + reach and y0 - reach <= py <= y1 + reach)
