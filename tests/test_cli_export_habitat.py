"""`sagebench export-habitat`: the goal tasks' episodes as habitat-lab datasets, read back as habitat-lab's own
dataset classes would (tests/habitat_datasets.py re-implements them)."""

from __future__ import annotations

import hashlib
import json
import math
import shutil

import numpy as np
import pytest

from sagebench.episodes.shards import read_episodes, write_shards
from sagebench.episodes.tasks import TASK_SCHEMA, row_task
from sagebench.vlnce.frame import from_habitat, rotation_to_yaw
from tests.habitat_datasets import objectnav_dataset, pointnav_episodes
from tests.test_cli_sage_tasks import SCENE, task_run  # noqa: F401 (the run with rows of every task)


@pytest.fixture(scope="module")
def habitat_export(task_run, tmp_path_factory):  # noqa: F811
    from sagebench.cli import main

    out = tmp_path_factory.mktemp("habitat")
    with pytest.raises(SystemExit) as exc:
        main(["export-habitat", str(task_run), "--out", str(out)])
    assert exc.value.code in (0, None)
    return out


def _rows(run, task):
    return [r for r in read_episodes(run / "episodes" / SCENE).to_pylist() if row_task(r) == task]


def _yaw_gap(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2 * math.pi))


@pytest.mark.parametrize("task", ["pointnav", "imagenav"])
def test_pointnav_and_imagenav_load_as_habitat_s_pointnav_v1(task_run, habitat_export, task):  # noqa: F811
    rows = {r["episode_id"]: r for r in _rows(task_run, task)}
    marker = json.loads((habitat_export / "habitat_export.json").read_text())
    assert marker["tasks"][task]["type"] == "PointNav-v1"
    split = next(iter(marker["tasks"][task]["episodes"]))
    path = habitat_export / marker["tasks"][task]["data_path"].format(split=split)
    episodes = pointnav_episodes(path, scenes_dir=str(habitat_export / "scenes"))
    assert sorted(e["episode_id"] for e in episodes) == sorted(rows)
    for ep in episodes:
        row = rows[ep["episode_id"]]
        assert (habitat_export / "scenes" / ep["scene_id"]).is_file()
        assert np.allclose(from_habitat(ep["start_position"]), row["start_position"])
        assert _yaw_gap(rotation_to_yaw(ep["start_rotation"]), row["start_yaw"]) < 1e-9
        assert np.allclose(from_habitat(ep["goals"][0]["position"]), row["goal_position"])
        assert ep["goals"][0]["radius"] == row["goal_radius"]
        if task == "imagenav":
            assert _yaw_gap(rotation_to_yaw(ep["info"]["goal_rotation"]), row["goal_yaw"]) < 1e-9
            assert ep["info"]["goal_image"] == row["goal_image"]


def test_objectnav_loads_as_habitat_s_objectnav_v1_with_every_instance_a_goal(task_run, habitat_export):  # noqa: F811
    rows = {r["episode_id"]: r for r in _rows(task_run, "objectnav")}
    views_of = {}  # category -> every viewpoint of its episodes: habitat-lab keeps one goal set per category
    for r in rows.values():
        views_of.setdefault(r["goal_category"], set()).update(map(tuple, r["goal_viewpoints"]))
    marker = json.loads((habitat_export / "habitat_export.json").read_text())
    assert marker["tasks"]["objectnav"]["type"] == "ObjectNav-v1"
    split = next(iter(marker["tasks"]["objectnav"]["episodes"]))
    data = objectnav_dataset(habitat_export / marker["tasks"]["objectnav"]["data_path"].format(split=split),
                             scenes_dir=str(habitat_export / "scenes"))
    assert len(data["episodes"]) == len(rows)
    for ep in data["episodes"]:
        row = rows[ep["info"]["sagebench_episode_id"]]
        assert ep["object_category"] == row["goal_category"] in data["category_to_task_category_id"]
        assert sorted(g["object_id"] for g in ep["goals"]) == sorted(row["goal_instance_ids"])
        assert {g["object_category"] for g in ep["goals"]} == {row["goal_category"]}
        views = [from_habitat(v["agent_state"]["position"]) for g in ep["goals"] for v in g["view_points"]]
        assert np.allclose(sorted(map(tuple, views)), sorted(views_of[row["goal_category"]]))
        assert np.allclose(from_habitat(ep["start_position"]), row["start_position"])


def test_tasks_without_a_habitat_format_are_left_out_and_counted(task_run, run_cli, tmp_path):  # noqa: F811
    code, out, err = run_cli("export-habitat", task_run, "--out", tmp_path / "h")
    assert code == 0, err
    counts = {t: len(_rows(task_run, t)) for t in ("nogoal", "vln")}
    assert out.splitlines()[-1] == f"left out (no habitat-lab dataset format): nogoal {counts['nogoal']}, vln {counts['vln']}"
    assert sorted(p.name for p in (tmp_path / "h").iterdir() if p.name != ".sagebench.lock") == \
        ["habitat_export.json", "imagenav", "objectnav", "pointnav", "scenes"]
    first = next((tmp_path / "h" / "pointnav").rglob("*.json.gz")).read_bytes()
    assert run_cli("export-habitat", task_run, "--out", tmp_path / "h")[0] == 0  # again into its own output
    assert next((tmp_path / "h" / "pointnav").rglob("*.json.gz")).read_bytes() == first


def test_a_run_without_goal_task_episodes_gets_one_line_and_nothing_is_written(demo_eval_run, run_cli, tmp_path):
    before = {str(p): hashlib.sha256(p.read_bytes()).hexdigest() for p in demo_eval_run.rglob("*") if p.is_file()}
    code, out, err = run_cli("export-habitat", demo_eval_run, "--out", tmp_path / "h")
    assert (code, out) == (2, "")
    assert err == f"error: {demo_eval_run}: no objectnav, pointnav or imagenav episodes in the run\n"
    assert not (tmp_path / "h").exists()
    assert {str(p): hashlib.sha256(p.read_bytes()).hexdigest() for p in demo_eval_run.rglob("*") if p.is_file()} == before


def test_every_split_s_objectnav_file_numbers_the_categories_alike(task_run, run_cli, tmp_path):  # noqa: F811
    """A model trained on one split's ObjectGoalSensor ids is evaluated on another's: the ids must agree, also for an
    export of one split alone (each split's own categories numbered from 0 gave 'bed' two ids)."""
    run = tmp_path / "run"
    shutil.copytree(task_run / "scenes", run / "scenes")
    rows = read_episodes(task_run / "episodes" / SCENE).to_pylist()
    objectnav = [r for r in rows if row_task(r) == "objectnav"][:2]
    assert len(objectnav) == 2
    moved = [dict(objectnav[0], split="train"), dict(objectnav[1], split="test", goal_category="aaa_first")]
    (run / "episodes" / SCENE).mkdir(parents=True)
    write_shards(moved, run / "episodes" / SCENE, 2**27, TASK_SCHEMA)
    assert run_cli("export-habitat", run, "--out", tmp_path / "all")[0] == 0
    assert run_cli("export-habitat", run, "--out", tmp_path / "train", "--split", "train")[0] == 0
    maps = [objectnav_dataset(tmp_path / out / "objectnav" / s / f"{s}.json.gz",
                              scenes_dir=str(tmp_path / out / "scenes"))["category_to_task_category_id"]
            for out, s in (("all", "train"), ("all", "test"), ("train", "train"))]
    want = {c: i for i, c in enumerate(sorted({"aaa_first", objectnav[0]["goal_category"]}))}
    assert maps == [want, want, want]


def test_objectnav_view_points_face_their_object_and_say_what_of_it_is_in_sight(task_run, run_cli, tmp_path):  # noqa: F811
    """habitat-lab reads a view point as ObjectViewLocation(agent_state=AgentState(position, rotation), iou)
    (habitat-lab object_nav_dataset.py:80-86, object_nav_task.py:47-67; tests/habitat_datasets.py): each view point
    turns the agent level to face its instance's centre, as habitat's view point generator does
    (datasets/rearrange/viewpoints.py at 6f568c0, lines 124-128: the direction to the object, y zeroed, from -Z),
    and its iou is the share of the instance's footprint in sight: 1 from open floor beside it, 0 from behind the
    nearest wall (main wrote the identity rotation and null)."""
    from shapely.geometry import Point, Polygon

    from sagebench.topdown.semantic_map import read_semantic_map

    smap = read_semantic_map(task_run / "scenes" / SCENE / "semantic_map.json")
    walls = [Polygon(p[0], p[1:]) for i in smap.instances if i.kind == "wall" for p in i.polygon.coordinates]
    chosen = max((i for i in smap.instances if i.kind == "object" and i.polygon.coordinates),
                 key=lambda i: min(w.distance(Polygon(i.polygon.coordinates[0][0])) for w in walls))
    centre = np.array(Polygon(chosen.polygon.coordinates[0][0]).centroid.coords[0])
    wall = min(walls, key=lambda w: w.distance(Point(centre)))
    near = np.array(wall.exterior.interpolate(wall.exterior.project(Point(centre))).coords[0])
    away = (near - centre) / np.linalg.norm(near - centre)
    behind, beside = near + 0.5 * away, centre - (np.linalg.norm(near - centre) - 0.3) * away
    row = dict(next(r for r in _rows(task_run, "objectnav")), goal_category=chosen.category,
               goal_instance_ids=[chosen.instance_id], goal_viewpoints=[[*behind, 0.0], [*beside, 0.0]])
    run = tmp_path / "run"
    shutil.copytree(task_run / "scenes", run / "scenes")
    (run / "episodes" / SCENE).mkdir(parents=True)
    write_shards([row], run / "episodes" / SCENE, 2**27, TASK_SCHEMA)
    assert run_cli("export-habitat", run, "--out", tmp_path / "h")[0] == 0
    data = objectnav_dataset(next((tmp_path / "h" / "objectnav").rglob("*.json.gz")))
    (goal,) = data["episodes"][0]["goals"]
    views = {tuple(np.round(from_habitat(v["agent_state"]["position"])[:2], 6)): v for v in goal["view_points"]}
    assert [views[tuple(np.round(p, 6))]["iou"] for p in (behind, beside)] == [0.0, 1.0]
    mesh_centre = from_habitat(goal["position"])
    for xy, view in views.items():
        x, y, z, w = view["agent_state"]["rotation"]
        assert x == z == 0.0 and math.isclose(y * y + w * w, 1.0)
        facing = math.atan2(mesh_centre[1] - xy[1], mesh_centre[0] - xy[0])
        assert _yaw_gap(rotation_to_yaw(view["agent_state"]["rotation"]), facing) < 1e-6
