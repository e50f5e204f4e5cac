"""`export-sage` and `import-sage-episodes` for every task: each task's file is the one SAGE-Bench's
`run_benchmark.py --task-type` reads (tests/sage_benchmark.py re-implements its reading), and SAGE's no-goal
episodes come in with their start poses instead of being dropped."""

from __future__ import annotations

import hashlib
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from sagebench.episodes.shards import read_episodes, write_shards
from sagebench.episodes.tasks import NOGOAL_INSTRUCTION, TASK_SCHEMA, goal_image_recipe, pointgoal_polar, row_task
from sagebench.scene.loader import load_scene
from tests.sage_benchmark import run_benchmark, sage_heading
from tests.test_cli_sage_episodes import _plain_sage_file

SCENE = "demo_apartment_0"
TASK_TYPE = {"vln": "vln", "nogoal": "nogoalnav", "objectnav": "objectnav", "pointnav": "pointnav",
             "imagenav": "imgnav"}


def _hex(*parts: str) -> str:
    return hashlib.sha256("|".join(parts).encode()).hexdigest()[:16]


def task_rows(rows: list[dict], spec) -> list[dict]:
    """Rows of every other task made from vln rows, filled as docs/tasks.md's contract says."""
    category = {o.instance_id: o.category for o in spec.objects}
    out = []
    firsts = {r["trajectory_id"]: r for r in reversed(rows) if r["goal_instance_id"] is not None}  # one a path
    for r in sorted(firsts.values(), key=lambda r: r["trajectory_id"])[:3]:
        (x, y, _), (gx, gy, _), yaw = r["start_position"], r["goal_position"], r["start_yaw"]
        own = {"instruction_level": None, "instruction_type": None, "instruction_text": None,
               "instruction_source": None}
        cat = category[r["goal_instance_id"]]
        variants = {
            "nogoal": {"goal_position": r["start_position"], "goal_radius": 0.0, "geodesic_distance": 0.0,
                       "reference_path": r["reference_path"][:1], "goal_instance_id": None,
                       "goal_room": r["start_room"], "budget_s": 80.0, "budget_steps": 160,
                       "instruction_text": NOGOAL_INSTRUCTION, "instruction_source": "template"},
            "objectnav": {"goal_category": cat, "goal_viewpoints": [r["goal_position"]],
                          "goal_instance_ids": [o.instance_id for o in spec.objects if o.category == cat]},
            "pointnav": {"goal_radius": 0.2, "goal_polar": list(pointgoal_polar(x, y, yaw, gx, gy))},
            "imagenav": {"goal_yaw": r["reference_path"][-1][3],
                         "goal_image": goal_image_recipe(gx, gy, r["reference_path"][-1][3])},
        }
        for task, fields in variants.items():
            tid = _hex(r["trajectory_id"], task)
            out.append({**r, **own, "task": task, "trajectory_id": tid, "episode_id": _hex(tid, "0"), **fields})
    return out


@pytest.fixture(scope="module")
def task_run(demo_eval_run, tmp_path_factory) -> Path:
    """The demo run with rows of every task: its vln rows and three of each other task."""
    run = tmp_path_factory.mktemp("tasks") / "run"
    shutil.copytree(demo_eval_run / "scenes", run / "scenes")
    rows = read_episodes(demo_eval_run / "episodes" / SCENE).to_pylist()
    spec = load_scene(run / "scenes" / SCENE).spec
    (run / "episodes" / SCENE).mkdir(parents=True)
    write_shards([dict(r, task="vln") for r in rows] + task_rows(rows, spec), run / "episodes" / SCENE, 2**27,
                 TASK_SCHEMA)
    return run


@pytest.fixture(scope="module")
def task_export(task_run, tmp_path_factory) -> Path:
    from sagebench.cli import main

    out = tmp_path_factory.mktemp("sage_tasks")
    with pytest.raises(SystemExit) as exc:
        main(["export-sage", str(task_run), "--out", str(out)])
    assert exc.value.code in (0, None)
    return out


def _file(out: Path, task: str) -> Path:
    tail = Path(SCENE) / f"trajectories_{SCENE}.json"
    return out / tail if task == "vln" else out / TASK_TYPE[task] / tail


def _angle(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2 * math.pi))


def test_each_task_is_a_file_of_its_own_that_sage_bench_runs_as_that_task(task_run, task_export):
    rows = read_episodes(task_run / "episodes" / SCENE).to_pylist()
    marker = json.loads((task_export / "sage_export.json").read_text())
    assert sorted(marker["tasks"]) == ["imgnav", "nogoalnav", "objectnav", "pointnav"]
    for task, sage_type in TASK_TYPE.items():
        mine = [r for r in rows if row_task(r) == task and (task != "vln" or r["instruction_text"] is not None)]
        episodes = run_benchmark(_file(task_export, task), sage_type)
        assert len(episodes) == len(mine), task
        if task == "vln":
            continue  # test_cli_sage_episodes checks the vln file
        by_trajectory = {r["trajectory_id"]: r for r in mine}  # one row per trajectory here
        for e in episodes:
            r = by_trajectory[e["episode_id"].rsplit("-", 1)[0]]  # SAGE's "<trajectory_id>-<k>"
            assert e["start_position"][:2] == [-r["start_position"][0], -r["start_position"][1]]
            assert _angle(sage_heading(e["start_rotation"]), r["start_yaw"] + math.pi) < 1e-9
            if task == "nogoal":
                assert e["goal"] is None and e["told"] == NOGOAL_INSTRUCTION and e["instruction_type"] == "Goal-less"
            else:
                assert e["goal"][:2] == [-r["goal_position"][0], -r["goal_position"][1]]
    vln = run_benchmark(_file(task_export, "vln"), "vln")
    assert "Goal-less" not in {e["instruction_type"] for e in vln}  # no no-goal episode scored by the goal criterion


def test_the_sample_fields_sage_s_task_classes_read(task_run, task_export):
    rows = {r["trajectory_id"]: r for r in read_episodes(task_run / "episodes" / SCENE).to_pylist()}
    for task, key in (("nogoal", "task_type"), ("objectnav", "target_object"), ("pointnav", "goal_position"),
                      ("imagenav", "target_image_position")):
        for sample in json.loads(_file(task_export, task).read_text())["scenes"][0]["samples"]:
            r = rows[sample["trajectory_id"]]
            want = {"task_type": "no_goal_exploration", "target_object": r["goal_category"],
                    "goal_position": sample["points"][-1]["position"],
                    "target_image_position": sample["points"][-1]["position"]}[key]
            assert sample[key] == want, task
            if task == "imagenav":
                assert sample["target_image"] == r["goal_image"]


def test_importing_each_task_s_file_gives_back_its_rows(task_run, task_export, run_cli, tmp_path):
    before = read_episodes(task_run / "episodes" / SCENE).to_pylist()
    for task in ("nogoal", "objectnav", "pointnav", "imagenav"):
        run = tmp_path / task
        shutil.copytree(task_run / "scenes", run / "scenes")
        code, out, err = run_cli("import-sage-episodes", _file(task_export, task), "--run", run)
        assert code == 0, err
        after = {r["episode_id"]: r for r in read_episodes(run / "episodes" / SCENE).to_pylist()}
        mine = [r for r in before if row_task(r) == task]
        assert sorted(after) == sorted(r["episode_id"] for r in mine), task
        for r in mine:
            for col, value in r.items():
                if isinstance(value, (float, list)) and col != "goal_instance_ids":
                    assert np.allclose(after[r["episode_id"]][col], value, atol=1e-9), (task, col)
                else:
                    assert after[r["episode_id"]][col] == value, (task, col)


def test_a_sage_no_goal_file_comes_in_and_goes_back_out_with_its_start_poses(demo_eval_run, run_cli, tmp_path):
    """SAGE-3D's Goal-less instructions: no-goal episodes from their sample's start, exported to the file SAGE runs
    with --task-type nogoalnav, whose reader then starts them where SAGE's own file did."""
    assert run_cli("export-sage", demo_eval_run, "--out", tmp_path / "first")[0] == 0
    plain = _plain_sage_file(tmp_path / "trajectories_0.json", _file(tmp_path / "first", "vln"), ("Goal-less",))
    run = tmp_path / "run"
    shutil.copytree(demo_eval_run / "scenes", run / "scenes")
    code, out, err = run_cli("import-sage-episodes", plain, "--run", run, "--scene", SCENE)
    assert code == 0, err
    samples = json.loads(plain.read_text())["scenes"][0]["samples"]
    rows = read_episodes(run / "episodes" / SCENE).to_pylist()
    nogoal = [r for r in rows if row_task(r) == "nogoal"]
    assert len(nogoal) == len(samples) == 8
    assert {r["instruction_text"] for r in nogoal} == {"Look around."}
    assert {(r["budget_s"], r["budget_steps"], r["goal_radius"]) for r in nogoal} == {(80.0, 160, 0.0)}
    code, out, err = run_cli("export-sage", run, "--out", tmp_path / "again")
    assert code == 0, err
    assert out.splitlines()[1] == f"nogoal: {tmp_path / 'again' / 'nogoalnav'} (run_benchmark.py --task-type nogoalnav)"
    again = run_benchmark(_file(tmp_path / "again", "nogoal"), "nogoalnav")
    starts = sorted((s["points"][0]["position"][:2], s["points"][0]["rotation"]) for s in samples)
    got = sorted((e["start_position"][:2], e["start_rotation"]) for e in again)
    assert len(got) == len(starts)
    for (p, q), (p2, q2) in zip(starts, got):
        assert np.allclose(p, p2, atol=1e-9) and _angle(sage_heading(q), sage_heading(q2)) < 1e-9
    vln = run_benchmark(_file(tmp_path / "again", "vln"), "vln")
    assert "Look around." not in {e["instruction"] for e in vln}


def _tree(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def test_a_sage_objectnav_sample_gets_the_viewpoints_gen_trajectories_gives_its_category(demo_eval_run, run_cli,
                                                                                         tmp_path):
    """SAGE's ObjectNav samples name a category and no viewpoints: they are found on import as gen-trajectories
    finds them, the main region's navigable cells within the success radius of any instance."""
    assert run_cli("export-sage", demo_eval_run, "--out", tmp_path / "first")[0] == 0
    plain = _plain_sage_file(tmp_path / "plain.json", _file(tmp_path / "first", "vln"), ())
    doc = json.loads(plain.read_text())
    doc["scenes"][0]["samples"] = [dict(s, target_object="bed") for s in doc["scenes"][0]["samples"][:2]]
    plain.write_text(json.dumps(doc))
    runs = {}
    for name, args in (("imported", ["import-sage-episodes", plain, "--scene", SCENE, "--goal-radius", "1", "--run"]),
                       ("generated", ["gen-trajectories", "--tasks", "objectnav", "--objectnav-categories", "bed",
                                      "--task-episodes", "1"])):
        runs[name] = tmp_path / name
        shutil.copytree(demo_eval_run / "scenes", runs[name] / "scenes")
        code, _, err = run_cli(*args, runs[name])
        assert code == 0, err
    imported, generated = (read_episodes(runs[n] / "episodes" / SCENE).to_pylist() for n in ("imported", "generated"))
    assert {(row_task(r), r["goal_category"], r["goal_radius"]) for r in imported} == {("objectnav", "bed", 1.0)}
    assert len({r["trajectory_id"] for r in imported}) == 2
    assert all(r["goal_instance_ids"] == generated[0]["goal_instance_ids"] for r in imported)
    assert all(r["goal_viewpoints"] == generated[0]["goal_viewpoints"] for r in imported)


@pytest.mark.parametrize(("edit", "args", "message"), [
    (lambda s: s.update(target_object="unicorn"), (),
     "{f}: scenes[0].samples[0].target_object: category 'unicorn' has no instance in scene 'demo_apartment_0'"),
    (lambda s: s.update(goal_position=s["points"][-1]["position"], points=s["points"][:1]), (),
     "{f}: scenes[0].samples[0].points: 1 point: a pointnav sample is a path, its start and goal at least"),
    (lambda s: s.update(target_object="bed"), ("--goal-radius", "0.01"),
     "{f}: scenes[0].samples[0].target_object: no navigable cell of the main region within 0.01 m of a bed "
     "instance: no goal viewpoint"),
])
def test_a_task_sample_missing_what_its_task_needs_gets_one_line(demo_eval_run, run_cli, tmp_path, edit, args,
                                                                 message):
    assert run_cli("export-sage", demo_eval_run, "--out", tmp_path / "first")[0] == 0
    plain = _plain_sage_file(tmp_path / "plain.json", _file(tmp_path / "first", "vln"))
    doc = json.loads(plain.read_text())
    edit(doc["scenes"][0]["samples"][0])
    plain.write_text(json.dumps(doc))
    run = tmp_path / "run"
    shutil.copytree(demo_eval_run / "scenes", run / "scenes")
    before = _tree(tmp_path)
    code, out, err = run_cli("import-sage-episodes", plain, "--run", run, "--scene", SCENE, *args)
    assert (code, out, err) == (2, "", f"error: {message.format(f=plain)}\n")
    assert _tree(tmp_path) == before
