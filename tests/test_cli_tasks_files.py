"""gen-trajectories --tasks on the tiny scene, then both writers: every task's export-sage file is read by SAGE-Bench's
reader as its task and imports back to the same rows, and export-habitat's files load with habitat-lab's loaders
(tests/sage_benchmark.py, tests/habitat_datasets.py)."""

from __future__ import annotations

import json
import shutil

from sagebench.episodes.shards import read_episodes
from sagebench.episodes.tasks import row_task
from tests.habitat_datasets import objectnav_dataset, pointnav_episodes
from tests.sage_benchmark import run_benchmark
from tests.test_episodes_tasks import ALL, tiny_built  # noqa: F401 (the tiny scene built)

SAGE_TYPES = {"nogoal": "nogoalnav", "objectnav": "objectnav", "pointnav": "pointnav", "imagenav": "imgnav"}
KEPT = ("task", "goal_category", "goal_instance_ids", "goal_viewpoints", "goal_polar", "goal_image", "goal_yaw",
        "budget_s", "budget_steps", "split", "instruction_text", "start_position", "goal_position")


def test_generated_task_episodes_through_both_writers(tiny_built, run_cli, tmp_path):  # noqa: F811
    run = tmp_path / "run"
    shutil.copytree(tiny_built, run)
    code, _, err = run_cli("gen-trajectories", run, "--per-scene", "4", "--min-geodesic", "1", "--tasks", ALL,
                           "--task-episodes", "6")
    assert code == 0, err
    sid = next((run / "episodes").iterdir()).name
    rows = read_episodes(run / "episodes" / sid).to_pylist()
    assert run_cli("export-sage", run, "--out", tmp_path / "sage")[0] == 0
    for task, sage_type in SAGE_TYPES.items():
        path = tmp_path / "sage" / sage_type / sid / f"trajectories_{sid}.json"
        mine = [r for r in rows if row_task(r) == task]
        assert len(run_benchmark(path, sage_type)) == len(mine) == 6, task
        back_run = tmp_path / task
        shutil.copytree(run / "scenes", back_run / "scenes")
        code, _, err = run_cli("import-sage-episodes", path, "--run", back_run)
        assert code == 0, err
        back = {r["episode_id"]: r for r in read_episodes(back_run / "episodes" / sid).to_pylist()}
        assert sorted(back) == sorted(r["episode_id"] for r in mine), task
        for r in mine:
            assert {k: back[r["episode_id"]][k] for k in KEPT} == {k: r[k] for k in KEPT}, task
    assert run_cli("export-habitat", run, "--out", tmp_path / "habitat")[0] == 0
    marker = json.loads((tmp_path / "habitat" / "habitat_export.json").read_text())
    assert sorted(marker["tasks"]) == ["imagenav", "objectnav", "pointnav"]
    for task, entry in marker["tasks"].items():
        assert sum(entry["episodes"].values()) == 6
        for split, n in entry["episodes"].items():
            path = tmp_path / "habitat" / entry["data_path"].format(split=split)
            loaded = objectnav_dataset(path)["episodes"] if task == "objectnav" else pointnav_episodes(path)
            assert len(loaded) == n
