"""Episode rows of the goal tasks -> habitat-lab's dataset files for them, positions in habitat's frame.

PointNav and ImageNav: habitat-lab's PointNav-v1 format (its ImageNav task reads PointNav-v1 files; its
ImageGoalSensor renders the goal image at goals[0].position itself). Each episode has exactly the fields
habitat-lab's NavigationEpisode takes: episode_id, scene_id, start_position, start_rotation,
goals [{position, radius}], info (geodesic_distance, and sagebench's episode and trajectory ids; ImageNav also the
goal camera's rotation and sagebench's goal_image, since habitat's sensor turns the camera at random).

ObjectNav: habitat-lab's ObjectNav-v1 format. Its loader takes the goals once per "<scene file name>_<category>"
(goals_by_category): one ObjectGoal per instance of the category (object_id the instance id, position its mesh
centre, view_points the episode's goal viewpoints nearest that instance), both category maps
(category_to_task_category_id, and category_to_scene_annotation_category_id, the same numbers: sagebench's GLBs carry
no semantic annotation), and its episodes with object_category and goals [] (the loader fills them). It numbers
episodes "0", "1", ... itself, so sagebench's episode id is in info.

A view point is habitat's ObjectViewLocation: agent_state (position, and a rotation turning the agent to face the
instance's centre, level, as habitat-lab's view point generator turns it: datasets/rearrange/viewpoints.py) and
iou. habitat's generator fills iou with the share of a semantic render's pixels the object covers (summed over
three camera tilts), which takes a render per view point; sagebench's view points are chosen by distance alone,
so its iou is what its map can say of the view: the share of the instance's footprint in sight from the view
point, walls and closed doors blocking the view (instructions/sight.py): 1 in open view, 0 behind a wall.
"""

from __future__ import annotations

import gzip
import json
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from sagebench.vlnce.episodes import scene_glb_path
from sagebench.vlnce.frame import to_habitat, yaw_to_rotation

POINT_FORMAT = "PointNav-v1"
OBJECT_FORMAT = "ObjectNav-v1"
HABITAT_TASKS = {"objectnav": OBJECT_FORMAT, "pointnav": POINT_FORMAT, "imagenav": POINT_FORMAT}


@dataclass(frozen=True)
class SceneObjects:
    """What ObjectNav's goals say of a scene's instances: each one's world mesh centre [3], and the share of its
    footprint in sight from view points (instance id, [K, 2] world m) -> [K] in [0, 1]."""

    centres: Mapping[int, Sequence[float]]
    seen: Callable[[int, np.ndarray], np.ndarray]


def _floats(v) -> list[float]:
    return [float(x) for x in np.asarray(v, dtype=np.float64).reshape(-1)]


def _episode(row: Mapping[str, Any]) -> dict[str, Any]:
    """The NavigationEpisode fields of a goal task's row."""
    return {
        "episode_id": row["episode_id"],
        "scene_id": scene_glb_path(row["scene_id"]),
        "start_position": _floats(to_habitat(row["start_position"])),
        "start_rotation": yaw_to_rotation(float(row["start_yaw"])),
        "info": {"geodesic_distance": float(row["geodesic_distance"]), "sagebench_episode_id": row["episode_id"],
                 "sagebench_trajectory_id": row["trajectory_id"]},
    }


def point_episode(row: Mapping[str, Any]) -> dict[str, Any]:
    """A pointnav or imagenav row as a PointNav-v1 episode."""
    ep = _episode(row)
    ep["goals"] = [{"position": _floats(to_habitat(row["goal_position"])), "radius": float(row["goal_radius"])}]
    if row["task"] == "imagenav":
        ep["info"].update(goal_rotation=yaw_to_rotation(float(row["goal_yaw"])), goal_image=row["goal_image"])
    return ep


def goals_key(scene_id: str, category: str) -> str:
    """habitat-lab's ObjectGoalNavEpisode.goals_key of a sagebench scene's category."""
    return f"{os.path.basename(scene_glb_path(scene_id))}_{category}"


def object_goals(row: Mapping[str, Any], objects: SceneObjects) -> list[dict[str, Any]]:
    """The ObjectGoals of an objectnav row: each instance of its category, with the row's goal viewpoints nearest
    it, each facing it (module docstring)."""
    ids = list(row["goal_instance_ids"])
    points = np.asarray(row["goal_viewpoints"], dtype=np.float64).reshape(-1, 3)
    where = np.array([objects.centres[i] for i in ids], dtype=np.float64)
    nearest = np.argmin(np.linalg.norm(points[:, None, :2] - where[None, :, :2], axis=2), axis=1)
    goals = []
    for k, iid in enumerate(ids):
        mine = points[nearest == k]
        goals.append({"object_id": iid, "object_category": row["goal_category"], "radius": float(row["goal_radius"]),
                      "position": _floats(to_habitat(where[k])),
                      "view_points": _view_points(mine, where[k], objects.seen(iid, mine[:, :2]))})
    return goals


def _view_points(points: np.ndarray, centre: np.ndarray, seen: np.ndarray) -> list[dict[str, Any]]:
    """habitat's ObjectViewLocations of view points [K, 3] around an instance centred at `centre` [3], each turned
    to face it, with its share in sight as iou."""
    yaws = np.arctan2(centre[1] - points[:, 1], centre[0] - points[:, 0])
    return [{"agent_state": {"position": _floats(to_habitat(p)), "rotation": yaw_to_rotation(float(yaw))},
             "iou": float(share)} for p, yaw, share in zip(points, yaws, seen)]


def object_dataset(rows: Sequence[Mapping[str, Any]], objects: Mapping[str, SceneObjects],
                   categories: Sequence[str]) -> dict[str, Any]:
    """The ObjectNav-v1 dataset of objectnav rows (`objects`: scene id -> its instances), the
    categories numbered in the order of `categories` (the run's, so every split's file numbers them alike); a
    scene's category has one set of goals: its rows' instances and viewpoints (each once)."""
    ids = {c: i for i, c in enumerate(categories)}
    merged: dict[str, dict] = {}
    for row in rows:
        key = goals_key(row["scene_id"], row["goal_category"])
        first = merged.setdefault(key, {**row, "goal_instance_ids": [], "goal_viewpoints": []})
        first["goal_instance_ids"] = sorted({*first["goal_instance_ids"], *row["goal_instance_ids"]})
        first["goal_viewpoints"] = sorted({*map(tuple, first["goal_viewpoints"]), *map(tuple, row["goal_viewpoints"])})
    goals = {key: object_goals(row, objects[row["scene_id"]]) for key, row in merged.items()}
    episodes = [{**_episode(r), "object_category": r["goal_category"], "goals": []} for r in rows]
    return {"episodes": episodes, "category_to_task_category_id": ids,
            "category_to_scene_annotation_category_id": dict(ids), "goals_by_category": goals}


def task_dataset_bytes(task: str, rows: Sequence[Mapping[str, Any]], objects: Mapping[str, SceneObjects],
                       categories: Sequence[str]) -> bytes:
    """The gzipped habitat dataset file of one task's rows (in their order; `categories`: objectnav's numbering);
    byte-identical for the same rows."""
    data = (object_dataset(rows, objects, categories) if task == "objectnav"
            else {"episodes": [point_episode(r) for r in rows]})
    return gzip.compress(json.dumps(data, sort_keys=True, separators=(",", ":")).encode(), mtime=0)
