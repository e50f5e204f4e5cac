"""The stages after gen-trajectories on a run holding every task's episodes (docs/tasks.md): `sagebench run` with
tasks in its config, validate, verify, report, export-vlnce and export-training, and each task run closed-loop by
the baselines and scored by evaluate. The run is the tiny scene through `sagebench run`; the closed loop runs on
the demo apartment and on the imported InteriorGS fixture too."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from test_fuzz_inputs import snapshot
from test_fuzz_safety import TOML

from sagebench.cli import main

TASKS = ("vln", "nogoal", "objectnav", "pointnav", "imagenav")
GOAL_TASKS = ("vln", "objectnav", "pointnav", "imagenav")
TASKS_TOML = TOML.replace("per_scene = 2\n", 'per_scene = 3\ntasks = ["vln", "nogoal", "objectnav", "pointnav", '
                                            '"imagenav"]\n') + "[gen_trajectories.task]\nepisodes = 3\n"


@pytest.fixture(scope="module")
def tasks_run(tiny_scene, tmp_path_factory) -> Path:
    """The tiny scene through `sagebench run` with every task, 3 episodes of each task but vln. Read-only."""
    folder = tmp_path_factory.mktemp("tasks_run")
    config = folder / "t.toml"
    config.write_text(TASKS_TOML.format(scene=tiny_scene, out=folder / "out"))
    with pytest.raises(SystemExit) as done:
        main(["-q", "run", str(config)])
    assert done.value.code in (0, None)
    return folder / "out"


def _with_tasks(scenes: Path, folder: Path) -> Path:
    """A run of the built `scenes` (a run's scenes/) with 3 episodes of every task, exported for the simulator."""
    from sagebench.stages.export_usd import export_usd

    run = folder / "run"
    shutil.copytree(scenes, run / "scenes")
    with pytest.raises(SystemExit) as done:
        main(["-q", "gen-trajectories", str(run), "--per-scene", "3", "--tasks", ",".join(TASKS), "--task-episodes",
              "3"])
    assert done.value.code in (0, None)
    export_usd(run, cache_dir=folder / "coacd_cache")
    return run


@pytest.fixture(scope="module")
def demo_tasks_run(demo_built_run, tmp_path_factory) -> Path:
    """The demo apartment with every task's episodes. Read-only."""
    return _with_tasks(demo_built_run / "scenes", tmp_path_factory.mktemp("demo_tasks"))


@pytest.fixture(scope="module")
def interiorgs_tasks_run(interiorgs_imported, tmp_path_factory) -> Path:
    """The imported InteriorGS fixture built, with every task's episodes. Read-only."""
    from sagebench.stages.build_scene import build_scene

    folder = tmp_path_factory.mktemp("interiorgs_tasks")
    build_scene(interiorgs_imported, folder / "built")
    return _with_tasks(folder / "built" / "scenes", folder)


def _rows(run: Path) -> list[dict]:
    return pq.read_table(sorted((run / "episodes").glob("*/part-*.parquet"))).to_pylist()


def _count(rows: list[dict]) -> dict[str, int]:
    return {t: sum(r["task"] == t for r in rows) for t in TASKS}


def test_run_writes_validates_and_records_every_task(tasks_run, run_cli):
    rows = _rows(tasks_run)
    assert all(n > 0 for n in _count(rows).values()), _count(rows)
    table = pq.read_table(tasks_run / "validation/tiny/part-00000.parquet").to_pylist()
    by_id = {r["trajectory_id"]: r for r in rows}
    assert {r["trajectory_id"] for r in table} == set(by_id)  # every task's trajectory was judged
    assert all(v["passed"] for v in table), [v for v in table if not v["passed"]]
    for v in table:
        assert v["task"] == by_id[v["trajectory_id"]]["task"]
        if v["task"] == "nogoal":  # no path to replay: its start pose was checked, and it has no goal to reach
            assert (v["outcome"], v["steps"], v["reached_goal"]) == ("start_only", 0, None)
        else:  # a goal task's reference path replayed to its goal
            assert v["steps"] > 0 and v["reached_goal"] and v["final_distance"] <= by_id[v["trajectory_id"]]["goal_radius"]
    report = json.loads((tasks_run / "reports/tiny/report.json").read_text())
    assert report["tasks"] == {t: len({r["trajectory_id"] for r in rows if r["task"] == t}) for t in sorted(TASKS)}
    assert report["metrics"]["steps"]["min"] > 0  # distributions of the replayed paths, not of nogoal's zeros
    manifest = json.loads((tasks_run / "manifest.json").read_text())
    assert manifest["config"]["gen_trajectories"]["tasks"] == list(TASKS)
    assert run_cli("verify", tasks_run)[0] == 0


@pytest.mark.parametrize("where, reasons", [((1.0, 1.0), ["collision", "start_off_map"]),  # inside the table
                                            ((-5.0, -5.0), ["start_off_map"])])  # off the map, touching nothing
def test_a_nogoal_start_off_the_map_fails_validation(where, reasons, tasks_run, tmp_path):
    from sagebench.settings.validate import ValidateConfig
    from sagebench.stages.validate import validate_scene

    run = tmp_path / "run"
    shutil.copytree(tasks_run, run)
    shard = sorted((run / "episodes/tiny").glob("part-*.parquet"))[0]
    table = pq.read_table(shard)
    rows = table.to_pylist()
    moved = next(r for r in rows if r["task"] == "nogoal")
    moved["start_position"][:2] = moved["reference_path"][0][:2] = list(where)
    pq.write_table(type(table).from_pylist(rows, schema=table.schema), shard)
    result = validate_scene(run, "tiny", ValidateConfig(frames_per_scene=0))
    assert result.failures == [(moved["trajectory_id"], tuple(reasons))]


def test_export_vlnce_leaves_the_other_tasks_out_and_says_how_many(tasks_run, run_cli, tmp_path):
    code, out, err = run_cli("-q", "export-vlnce", tasks_run, "--out", tmp_path / "vlnce")
    assert code == 0, err
    n = _count(_rows(tasks_run))
    assert (f"left out {sum(n.values()) - n['vln']} episodes of tasks other than vln (imagenav {n['imagenav']}, "
            f"nogoal {n['nogoal']}, objectnav {n['objectnav']}, pointnav {n['pointnav']}): R2R's format holds VLN "
            "episodes only") in out.splitlines()
    import gzip
    written = [e["episode_id"] for f in (tmp_path / "vlnce").glob("*/*[!t].json.gz")
               for e in json.loads(gzip.decompress(f.read_bytes()))["episodes"]]
    assert sorted(written) == sorted(r["episode_id"] for r in _rows(tasks_run) if r["task"] == "vln")


def test_export_training_leaves_the_other_tasks_out_and_says_how_many(tasks_run, run_cli, tmp_path):
    code, out, err = run_cli("-q", "export-training", tasks_run, "--out", tmp_path / "t", "--width", "16",
                             "--height", "16", "--renderer", "cpu")
    assert code == 0, err
    n = _count(_rows(tasks_run))
    assert (f"left out {sum(n.values()) - n['vln']} episodes of tasks other than vln (imagenav {n['imagenav']}, "
            f"nogoal {n['nogoal']}, objectnav {n['objectnav']}, pointnav {n['pointnav']}): export-training writes "
            "VLN episodes only") in out.splitlines()
    assert json.loads((tmp_path / "t/index.json").read_text())["episodes"] == n["vln"]


@pytest.mark.parametrize("command, expect", [
    (["export-vlnce", "{run}", "--out", "{out}"],
     "error: {run}: no episodes with an instruction in any split (only 12 episodes of tasks other than vln)"),
    (["export-training", "{run}", "--out", "{out}"],
     "error: {run}: no vln episodes to export (only 12 episodes of tasks other than vln (imagenav 3, nogoal 3, "
     "objectnav 3, pointnav 3))"),
])
def test_an_export_of_a_run_without_vln_episodes_is_refused(command, expect, tasks_run, run_cli, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(tasks_run, run)
    shard = sorted((run / "episodes/tiny").glob("part-*.parquet"))[0]
    table = pq.read_table(shard)
    pq.write_table(table.filter(np.array([t != "vln" for t in table.column("task").to_pylist()])), shard)
    before = snapshot(tmp_path)
    args = [a.format(run=run, out=tmp_path / "out") for a in command]
    code, out, err = run_cli(*args)
    assert (code, out, err) == (2, "", expect.format(run=run) + "\n")
    assert snapshot(tmp_path) == before


def _evaluate(run_cli, run: Path, predictions: Path, tmp_path: Path) -> dict:
    out = tmp_path / f"{predictions.stem}.json"
    code, _, err = run_cli("-q", "evaluate", "--run", run, "--predictions", predictions, "--out", out)
    assert code == 0, err
    doc = json.loads(out.read_text())
    return doc.get("by_task") or {"vln": doc["overall"]}  # VLN's predictions alone are scored as before tasks


@pytest.mark.parametrize("made", ["tasks_run", pytest.param("demo_tasks_run", marks=pytest.mark.slow),
                                  pytest.param("interiorgs_tasks_run", marks=pytest.mark.slow)])
def test_every_task_runs_closed_loop_and_is_scored(made, request, run_cli, tmp_path):
    """On the tiny scene, the demo apartment and the imported InteriorGS fixture, every task has episodes; the
    oracle succeeds on every goal task; a stationary agent never succeeds and covers nothing, scored per task alone
    and in one batch of every task."""
    tasks_run = request.getfixturevalue(made)
    assert all(n > 0 for n in _count(_rows(tasks_run)).values()), _count(_rows(tasks_run))
    stationary = []
    for task in TASKS:
        for agent in ("oracle", "stationary"):
            pred = tmp_path / f"{agent}_{task}.jsonl"
            code, _, err = run_cli("-q", "baseline", "--run", tasks_run, "--out", pred, "--agent", agent,
                                   "--task", task)
            assert code == 0, err
            scores = _evaluate(run_cli, tasks_run, pred, tmp_path)
            assert list(scores) == [task] and scores[task]["episodes"] == _count(_rows(tasks_run))[task]
            if agent == "oracle" and task in GOAL_TASKS:
                assert scores[task]["sr"] >= 0.95, (task, scores)
            if agent == "stationary":
                assert scores[task]["sr"] == 0.0 and scores[task].get("coverage", 0.0) < 0.02, (task, scores)
                stationary.append(pred.read_text())
    batch = tmp_path / "batch.jsonl"
    batch.write_text("".join(stationary))
    scores = _evaluate(run_cli, tasks_run, batch, tmp_path)
    assert sorted(scores) == sorted(TASKS) and all(s["sr"] == 0.0 for s in scores.values()), scores
    assert scores["nogoal"]["coverage"] < 0.02


@pytest.mark.parametrize("made, walled", [("tasks_run", False),  # the tiny room has no walls: some views are empty
                                          pytest.param("demo_tasks_run", True, marks=pytest.mark.slow),
                                          pytest.param("interiorgs_tasks_run", True, marks=pytest.mark.slow)])
def test_imagenav_s_goal_image_is_the_scene_s_view_from_the_goal_pose(made, walled, request):
    """An imagenav agent is shown the Gaussians' view from the goal camera (what `sagebench render --pose` gives
    there), not a placeholder: in a walled apartment it is a picture, and not the view at the start."""
    from sagebench.env import NavEnv
    from sagebench.settings.render import RenderConfig
    from sagebench.settings.rollout import EnvConfig
    from sagebench.stages.render import render_view

    run = request.getfixturevalue(made)
    env = NavEnv(run, EnvConfig(task="imagenav", width=32, height=24, observations=("rgb",), renderer="cpu"))
    for row in (r for r in _rows(run) if r["task"] == "imagenav"):
        seen, _ = env.reset(options={"episode_id": row["episode_id"]})
        (x, y, _), yaw = row["goal_position"], row["goal_yaw"]
        view = render_view(run, row["scene_id"], (x, y, yaw), RenderConfig(width=32, height=24, renderer="cpu")).rgb
        assert np.abs(seen["imagegoal"] - np.clip(view * 255.0, 0, 255)).max() <= 1.0, row["episode_id"]
        if walled:
            assert seen["imagegoal"].std() > 10 and np.abs(seen["imagegoal"] - seen["rgb"].astype(float)).mean() > 5


@pytest.mark.slow
@pytest.mark.parametrize("made", ["demo_tasks_run", "interiorgs_tasks_run"])
def test_the_explorer_covers_at_least_twice_what_a_random_walk_does(made, request, run_cli, tmp_path):
    run = request.getfixturevalue(made)
    coverage = {}
    for agent in ("explorer", "random"):
        pred = tmp_path / f"{agent}.jsonl"
        code, _, err = run_cli("-q", "baseline", "--run", run, "--out", pred, "--agent", agent, "--task", "nogoal")
        assert code == 0, err
        coverage[agent] = _evaluate(run_cli, run, pred, tmp_path)["nogoal"]["coverage"]
    assert coverage["explorer"] >= 2 * coverage["random"] > 0, coverage
