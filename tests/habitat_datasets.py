"""habitat-lab's PointNav-v1 and ObjectNav-v1 dataset loaders (ImageNav reads PointNav-v1 files), re-implemented
for the tests from the behaviour of habitat-lab's pointnav_dataset.py, object_nav_dataset.py, nav.py,
object_nav_task.py, core/dataset.py and core/simulator.py (habitat-lab cannot be installed here): not copied
and not imported.

What matters is what habitat-lab refuses: its episode and goal classes are attrs classes, so a key they do not
declare is a TypeError, and a declared field that must be set (not_none_validator) left out or null is a
ValueError. ObjectNav files carry both category maps with the same keys and their goals once per
"<scene file name>_<category>" (goals_by_category); the loader renumbers episodes "0", "1", ... and gives each
the goals of its key (a KeyError when there are none). ImageNav (habitat's ImageGoalSensor) renders its goal
image at goals[0].position.
"""

from __future__ import annotations

import gzip
import json
import os
from pathlib import Path
from typing import Any

DEFAULT_SCENE_PATH_PREFIX = "data/scene_datasets/"
# attrs class -> (fields that must be set and not null, fields that may be left out, fields without a default that
# may be null), as habitat-lab declares them
EPISODE = ({"episode_id", "scene_id", "start_position", "start_rotation", "goals"},
           {"scene_dataset_config", "additional_obj_config_paths", "info", "start_room", "shortest_paths"}, set())
OBJECT_EPISODE = (EPISODE[0], EPISODE[1] | {"object_category"}, set())
GOAL = ({"position"}, {"radius"}, set())
OBJECT_GOAL = ({"position", "object_id"},
               {"radius", "object_name", "object_name_id", "object_category", "room_id", "room_name", "view_points"},
               set())
VIEW_LOCATION = (set(), set(), {"agent_state", "iou"})
AGENT_STATE = (set(), {"rotation"}, {"position"})
PATH_POINT = (set(), {"action"}, {"position", "rotation"})


def build(kind: tuple[set[str], set[str], set[str]], name: str, fields: dict[str, Any]) -> dict[str, Any]:
    """`fields` as habitat-lab's attrs class `name` takes them: a TypeError for a key it does not declare or a
    field without a default left out, a ValueError for a not_none_validator field missing or null."""
    not_null, optional, positional = kind
    unknown = set(fields) - not_null - optional - positional
    if unknown:
        raise TypeError(f"{name}.__init__() got an unexpected keyword argument {sorted(unknown)[0]!r}")
    missing = positional - set(fields)
    if missing:
        raise TypeError(f"{name}.__init__() missing a required argument: {sorted(missing)[0]!r}")
    for key in sorted(not_null):
        if fields.get(key) is None:
            raise ValueError(f"{name}: argument {key!r} must be set")
    return dict(fields)


def _scene(episode: dict[str, Any], scenes_dir: str | None) -> None:
    if scenes_dir is not None:
        scene = episode["scene_id"]
        if scene.startswith(DEFAULT_SCENE_PATH_PREFIX):
            scene = scene[len(DEFAULT_SCENE_PATH_PREFIX):]
        episode["scene_id"] = os.path.join(scenes_dir, scene)


def _paths(episode: dict[str, Any]) -> None:
    for path in episode.get("shortest_paths") or []:
        for i, point in enumerate(path):
            path[i] = build(PATH_POINT, "ShortestPathPoint", point)


def _read(path: Path) -> dict[str, Any]:
    with gzip.open(path, "rt") as fh:
        return json.load(fh)


def pointnav_episodes(path: Path, scenes_dir: str | None = None) -> list[dict[str, Any]]:
    """PointNavDatasetV1.from_json of the gzipped file `path` (what ImageNav loads too)."""
    episodes = []
    for raw in _read(path)["episodes"]:
        ep = build(EPISODE, "NavigationEpisode", raw)
        _scene(ep, scenes_dir)
        ep["goals"] = [build(GOAL, "NavigationGoal", g) for g in ep["goals"]]
        _paths(ep)
        episodes.append(ep)
    return episodes


def goals_key(episode: dict[str, Any]) -> str:
    """ObjectGoalNavEpisode.goals_key."""
    return f"{os.path.basename(episode['scene_id'])}_{episode.get('object_category')}"


def _object_goal(raw: dict[str, Any]) -> dict[str, Any]:
    goal = build(OBJECT_GOAL, "ObjectGoal", raw)
    views = []
    for view in goal.get("view_points") or []:
        view = build(VIEW_LOCATION, "ObjectViewLocation", view)
        view["agent_state"] = build(AGENT_STATE, "AgentState", view["agent_state"])
        views.append(view)
    goal["view_points"] = views
    return goal


def objectnav_dataset(path: Path, scenes_dir: str | None = None) -> dict[str, Any]:
    """ObjectNavDatasetV1.from_json of the gzipped file `path`: its category maps, goals and episodes."""
    data = _read(path)
    task_ids = data["category_to_task_category_id"]
    scene_ids = data.get("category_to_scene_annotation_category_id", data.get("category_to_mp3d_category_id"))
    assert len(task_ids) == len(scene_ids) and set(task_ids) == set(scene_ids), \
        "category_to_task and category_to_mp3d must have the same keys"
    out = {"category_to_task_category_id": task_ids, "goals_by_category": {}, "episodes": []}
    if not data["episodes"]:
        return out
    assert "goals_by_category" in data, "sagebench writes goals once per category (no dedup_goals pass)"
    out["goals_by_category"] = {k: [_object_goal(g) for g in v] for k, v in data["goals_by_category"].items()}
    for i, raw in enumerate(data["episodes"]):
        ep = build(OBJECT_EPISODE, "ObjectGoalNavEpisode", raw)
        ep["episode_id"] = str(i)
        key = goals_key(ep)  # a file name: the same before and after the scenes directory is joined
        _scene(ep, scenes_dir)
        ep["goals"] = out["goals_by_category"][key]
        _paths(ep)
        out["episodes"].append(ep)
    return out
