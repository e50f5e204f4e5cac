"""`sagebench export-sage` and `import-sage-episodes`: SAGE-3D's GVLN files both ways.

SAGE-3D's reading is re-implemented in tests/sage_benchmark.py.
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from sagebench.episodes.shards import read_episodes
from sagebench.gvln.episodes import item_names
from sagebench.scene.loader import load_scene
from interiorgs_fixture import obb_corners
from tests.sage_benchmark import object_success, sage_adapter, sage_heading, sage_semantic_map

SCENE = "demo_apartment_0"


def _angle(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2 * math.pi))


@pytest.fixture(scope="module")
def exported(demo_eval_run, tmp_path_factory) -> Path:
    from sagebench.cli import main

    out = tmp_path_factory.mktemp("sage")
    with pytest.raises(SystemExit) as exc:
        main(["export-sage", str(demo_eval_run), "--out", str(out)])
    assert exc.value.code in (0, None)
    return out / SCENE / f"trajectories_{SCENE}.json"


def test_sage_s_reader_sees_our_starts_goals_headings_and_instructions(demo_eval_run, exported):
    rows = read_episodes(demo_eval_run / "episodes" / SCENE).to_pylist()
    rows = [r for r in rows if r["instruction_text"] is not None]
    spec = load_scene(demo_eval_run / "scenes" / SCENE).spec
    names = item_names(spec)
    episodes = sage_adapter(exported)
    assert len(episodes) == len(rows) and {e["scene_name"] for e in episodes} == {"0"}
    by_trajectory: dict[str, list[dict]] = {}
    for r in rows:
        by_trajectory.setdefault(r["trajectory_id"], []).append(r)
    sage = {e["episode_id"]: e for e in episodes}
    for tid, group in by_trajectory.items():
        for k, row in enumerate(group):
            e = sage[f"{tid}-{k}"]
            assert e["start_position"][:2] == [-row["start_position"][0], -row["start_position"][1]]
            assert e["goal"][:2] == [-row["goal_position"][0], -row["goal_position"][1]]
            # the same heading, seen in SAGE's frame (turned by 180 degrees)
            assert _angle(sage_heading(e["start_rotation"]), row["start_yaw"] + math.pi) < 1e-9
            assert e["instruction"] == row["instruction_text"]
            assert e["instruction_type"] == {"Attribute_Based": "Attribute-based", "Area_Based": "Area-based"}.get(
                row["instruction_type"], row["instruction_type"])
            assert e["start_item"] == names.get(row["start_instance_id"], row["start_room"])
            # a room goal ends at an object SAGE-Bench's evaluator can look up (the next test scores it)
            assert e["end_item"] == names[row["goal_instance_id"]] if row["goal_instance_id"] else (
                e["end_item"] in names.values())


def test_sage_bench_s_evaluator_scores_a_room_goal_by_the_object_it_ends_at(demo_eval_run, exported):
    scene = load_scene(demo_eval_run / "scenes" / SCENE)
    items = sorted((o for o in scene.spec.objects if o.kind in ("object", "door", "window")),
                   key=lambda o: o.instance_id)
    labels = [{"label": o.category, "bounding_box": [dict(zip("xyz", map(float, c)))
                                                     for c in obb_corners(scene.meshes[o.instance_id])]} for o in items]
    corners = np.array([[v["x"], v["y"]] for lab in labels for v in lab["bounding_box"]])
    lo, hi = np.floor(corners.min(axis=0)) - 1.05, np.ceil(corners.max(axis=0)) + 1  # cell centres on 0.1 m
    shape = np.ceil((hi - lo) / 0.1).astype(int)[::-1]
    smap = sage_semantic_map(labels, np.full(shape, 127, np.uint8), tuple(lo), 0.1)  # walls and outside all round
    samples = json.loads(exported.read_text())["scenes"][0]["samples"]
    room_goals = [s for s in samples if s["sagebench"]["goal_instance_id"] is None]
    assert room_goals
    for sample in room_goals:
        for ins in sample["instructions"]:
            assert object_success(smap, ins["end"], sample["points"][-1]["position"]) is True, ins["end"]
    marker = json.loads((exported.parents[1] / "sage_export.json").read_text())
    rows = read_episodes(demo_eval_run / "episodes" / SCENE).to_pylist()
    in_rooms = {r["trajectory_id"] for r in rows if r["goal_instance_id"] is None and r["instruction_text"]}
    assert len(in_rooms) == len(room_goals) + sum(marker.get("room_goals_left_out", {}).values())


def test_import_of_the_export_reproduces_the_episodes(demo_eval_run, exported, run_cli, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(demo_eval_run / "scenes", run / "scenes")
    code, out, err = run_cli("import-sage-episodes", exported, "--run", run)
    assert code == 0, err
    assert out.startswith(f"import-sage-episodes {SCENE}: 8 trajectories, ")
    before = read_episodes(demo_eval_run / "episodes" / SCENE).to_pylist()
    after = read_episodes(run / "episodes" / SCENE).to_pylist()
    assert len(after) == len(before)
    key = lambda r: r["episode_id"]  # noqa: E731
    for a, b in zip(sorted(before, key=key), sorted(after, key=key)):
        for col in a:
            if col in ("start_yaw", "reference_path", "geodesic_distance", "start_position", "goal_position"):
                assert np.allclose(a[col], b[col], atol=1e-9), col
            else:
                assert a[col] == b[col], col


def _plain_sage_file(path: Path, exported: Path, extra_types: tuple[str, ...] = ("Default",)) -> Path:
    """The export as SAGE-3D itself writes it: no sagebench keys, its own trajectory ids and types, plus an
    instruction of each of `extra_types` ("Default": "Go there.", "Goal-less": "Look around.")."""
    doc = json.loads(exported.read_text())
    for i, sample in enumerate(doc["scenes"][0]["samples"]):
        sample.pop("sagebench")
        sample["trajectory_id"] = str(i)
        for ins in sample["instructions"]:
            ins.pop("sagebench")
        first = sample["instructions"][0]
        said = {"Default": "Go there.", "Goal-less": "Look around."}
        sample["instructions"] += [dict(first, instruction_type=k, generated_instruction=said[k]) for k in extra_types]
    path.write_text(json.dumps(doc))
    return path


def test_sage_bench_s_own_episodes_run_in_the_closed_loop(demo_eval_run, exported, run_cli, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(demo_eval_run / "scenes", run / "scenes")
    sage_file = _plain_sage_file(tmp_path / "trajectories_0001_0.json", exported)
    code, out, err = run_cli("import-sage-episodes", sage_file, "--run", run, "--scene", SCENE)
    assert code == 0, err
    rows = read_episodes(run / "episodes" / SCENE).to_pylist()
    spec = load_scene(run / "scenes" / SCENE).spec
    names = {v: k for k, v in item_names(spec).items()}
    plain = json.loads(sage_file.read_text())["scenes"][0]["samples"]
    assert {(r["instruction_level"], r["instruction_type"]) for r in rows if r["instruction_text"] == "Go there."} == {
        ("low", "Single_Goal")}
    assert {r["split"] for r in rows} == {"test"} and {r["goal_radius"] for r in rows} == {0.5}
    assert {r["instruction_source"] for r in rows} == {"sage-bench"}
    assert {r["start_instance_id"] for r in rows} == {names.get(s["instructions"][0]["start"]) for s in plain}
    assert len({r["episode_id"] for r in rows}) == len(rows)
    preds = tmp_path / "oracle.jsonl"
    assert run_cli("rollout", "--run", run, "--policy", "oracle", "--obs", "none", "--out", preds)[0] == 0
    code, out, err = run_cli("evaluate", "--run", run, "--predictions", preds, "--out", tmp_path / "scores.json")
    assert code == 0, err
    scores = json.loads((tmp_path / "scores.json").read_text())
    assert scores["overall"]["episodes"] == len(rows) and scores["overall"]["sr"] == 1.0


@pytest.mark.parametrize(("edit", "message"), [
    (lambda d: d["scenes"][0]["samples"][0]["points"][0].__setitem__("rotation", [0.0, 0.0, 0.3, 0.95]),
     "{f}: scenes[0].samples[0].points[0].rotation: rotation [0.0, 0.0, 0.3, 0.95] turns about z: a trajectory in "
     "SAGE-3D's 2D map frame, not yet moved into its 3D frame by trajectory_2d_to_3d.py"),
    (lambda d: d["scenes"][0]["samples"][1].__setitem__("points", []),
     "{f}: scenes[0].samples[1].points: List should have at least 1 item after validation, not 0"),
    (lambda d: d["scenes"][0]["samples"][1].__setitem__("points", d["scenes"][0]["samples"][1]["points"][:1]),
     "{f}: scenes[0].samples[1].points: 1 point: a vln sample is a path, its start and goal at least"),
    (lambda d: d.__setitem__("scenes", []), "{f}: scenes: List should have at least 1 item after validation, not 0"),
    (lambda d: d["scenes"][0].__setitem__("scene_name", "839920"),
     "{f}: scene_name: the file is for scene '839920', and {run}/scenes has no scene of that name; name the scene "
     "with --scene"),
])
def test_bad_files_get_one_line_and_nothing_is_written(exported, demo_eval_run, run_cli, tmp_path, edit, message):
    run = tmp_path / "run"
    shutil.copytree(demo_eval_run / "scenes", run / "scenes")
    doc = json.loads(exported.read_text())
    edit(doc)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    code, out, err = run_cli("import-sage-episodes", bad, "--run", run)
    assert (code, out) == (2, "")
    assert err == f"error: {message.format(f=bad, run=run)}\n"
    assert not (run / "episodes").exists()


def test_an_interiorgs_scene_s_sage_offset_moves_exported_points_and_the_import_moves_them_back(demo_eval_run,
                                                                                               run_cli, tmp_path):
    run = tmp_path / "run"
    for part in ("scenes", "episodes"):
        shutil.copytree(demo_eval_run / part, run / part)
    spec_path = run / "scenes" / SCENE / "scene.json"
    offset = (-0.004, -0.002)  # what SAGE's format2-rounded map bounds put into its 3D frame (import-interiorgs)
    spec_path.write_text(json.dumps({**json.loads(spec_path.read_text()), "sage_offset": list(offset)}))
    code, _, err = run_cli("export-sage", run, "--out", tmp_path / "sage")
    assert code == 0, err
    before = read_episodes(run / "episodes" / SCENE).to_pylist()
    rows = {r["episode_id"]: r for r in before}
    doc = json.loads((tmp_path / "sage" / SCENE / f"trajectories_{SCENE}.json").read_text())
    for sample in doc["scenes"][0]["samples"]:
        row = rows[sample["instructions"][0]["sagebench"]["episode_id"]]
        for point, world in zip(sample["points"], row["reference_path"]):
            assert point["position"][:2] == pytest.approx([offset[0] - world[0], offset[1] - world[1]], abs=1e-12)
    code, _, err = run_cli("import-sage-episodes", tmp_path / "sage" / SCENE / f"trajectories_{SCENE}.json",
                           "--run", run)
    assert code == 0, err
    after = {r["episode_id"]: r for r in read_episodes(run / "episodes" / SCENE).to_pylist()}
    for eid, row in rows.items():
        if row["instruction_text"] is not None:
            assert np.allclose(after[eid]["reference_path"], row["reference_path"], atol=1e-9)
