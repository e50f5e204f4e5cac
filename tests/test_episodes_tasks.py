"""gen-trajectories --tasks: every task's episodes with the fields its task needs (docs/tasks.md), vln's outputs
unchanged byte for byte, and bad task input refused with one line."""

from __future__ import annotations

import hashlib
import math
import shutil
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from test_fuzz_inputs import snapshot

ALL = "vln,nogoal,objectnav,pointnav,imagenav"
# main 5c3adc2's gen-trajectories --per-scene 4 --min-geodesic 1 on the tiny scene (and its dataset card)
BEFORE_TASKS = {
    "episodes/tiny/part-train-00000.parquet": "cfc4811eb06066bf423f597906c82d08ec61fc81ef48648111af8bc63afa535d",
    "previews/tiny/paths.png": "87b22070aa9231f3d2d5a5bbaabcbd05e690d4a9c083aea80567ffbc8934c070",
    "card": "d76412c8920cd0258f8c3058cd25f42299fbc7ae49492719cee77db178cd6e62",
}
# what a vln config's settings dumped as before tasks existed: the stamps' keys and the manifest hash it
MAIN_SETTINGS = ["per_scene", "seed", "min_geodesic_m", "max_geodesic_m", "approach_max_m", "approach_tolerance_m",
                 "pair_mix", "shard_mb", "instructions", "goal_radius_m", "high_level_mix", "llm", "preview_paths",
                 "splits"]


@pytest.fixture(scope="module")
def tiny_built(tiny_scene, tmp_path_factory) -> Path:
    """The tiny scene built (scenes/ only). Read-only: copy it."""
    from sagebench.settings.build_scene import BuildSceneConfig, SplatConfig
    from sagebench.stages.build_scene import build_scene

    run = tmp_path_factory.mktemp("tasks") / "run"
    build_scene(tiny_scene, run, BuildSceneConfig(splats=SplatConfig(object_density=20.0, structure_density=5.0)))
    return run


def _copy(built: Path, where: Path) -> Path:
    shutil.copytree(built, where)
    return where


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def all_tasks(tiny_built, tmp_path_factory) -> Path:
    from sagebench.cli import main

    run = _copy(tiny_built, tmp_path_factory.mktemp("all") / "run")
    with pytest.raises(SystemExit) as done:
        main(["-q", "gen-trajectories", str(run), "--per-scene", "4", "--min-geodesic", "1", "--tasks", ALL,
              "--task-episodes", "6"])
    assert done.value.code in (0, None)
    return run


def test_tasks_vln_writes_the_same_bytes_as_before_tasks(tiny_built, tmp_path, run_cli):
    from sagebench.episodes.card import card_text
    from sagebench.settings.gen_trajectories import GenTrajectoriesConfig

    run = _copy(tiny_built, tmp_path / "run")
    code, _, err = run_cli("gen-trajectories", str(run), "--per-scene", "4", "--min-geodesic", "1", "--tasks", "vln")
    assert code == 0, err
    got = {p: _sha(run / p) for p in BEFORE_TASKS if p != "card"}
    assert {**got, "card": hashlib.sha256(card_text(run).encode()).hexdigest()} == BEFORE_TASKS
    assert "task" not in pq.read_schema(run / "episodes/tiny/part-train-00000.parquet").names
    assert list(GenTrajectoriesConfig(tasks=("vln",)).model_dump(mode="json")) == MAIN_SETTINGS


def test_every_task_has_the_fields_its_task_needs(all_tasks):
    from sagebench.episodes.load import load_episodes
    from sagebench.episodes.tasks import NOGOAL_INSTRUCTION, TASK_SCHEMA, pointgoal_polar

    episodes = load_episodes(all_tasks)
    by_task = {t: [e for e in episodes if e.task == t] for t in ALL.split(",")}
    assert {t: len(v) for t, v in by_task.items() if t != "vln"} == {"nogoal": 6, "objectnav": 6, "pointnav": 6,
                                                                     "imagenav": 6}
    assert len(by_task["vln"]) > 0
    for shard in (all_tasks / "episodes/tiny").glob("*.parquet"):
        assert pq.read_schema(shard).remove_metadata() == TASK_SCHEMA.remove_metadata()
    for e in by_task["nogoal"]:
        assert (e.budget_s, e.budget_steps, e.instruction, e.has_goal) == (80.0, 160, NOGOAL_INSTRUCTION, False)
        assert np.array_equal(e.goal, e.start) and e.goal_radius == 0.0
    for e in by_task["pointnav"]:
        assert e.goal_radius == 0.2
        assert e.goal_polar == pytest.approx(pointgoal_polar(e.start[0], e.start[1], e.start_yaw, e.goal[0], e.goal[1]))
        assert 1.0 <= e.geodesic_distance and e.goal_polar[0] <= e.geodesic_distance + 1e-9
    for e in by_task["imagenav"]:
        assert e.goal_radius == 1.0 and e.goal_image == f"render:{float(e.goal[0])!r},{float(e.goal[1])!r},{e.goal_yaw!r}"
    assert len({(e.start[0], e.start[1]) for e in by_task["nogoal"]}) == 6  # spread: no two at one cell


def test_objectnav_counts_every_instance_and_its_goal_is_the_nearest_viewpoint(all_tasks):
    from sagebench.episodes.load import load_episodes
    from sagebench.topdown.semantic_map import read_semantic_map

    smap = read_semantic_map(all_tasks / "scenes/tiny/semantic_map.json")
    for e in load_episodes(all_tasks, tasks={"objectnav"}):
        assert sorted(e.goal_instance_ids) == sorted(i.instance_id for i in smap.instances
                                                     if i.category == e.goal_category)
        assert e.goal_radius == 1.0 and e.instruction == f"Find the {e.goal_category}"
        assert any(np.allclose(e.goal, v) for v in e.goal_viewpoints)  # the goal is one of the viewpoints
        assert e.geodesic_distance >= 1.0


def test_task_episodes_are_the_same_bytes_on_every_run(all_tasks, tiny_built, tmp_path, run_cli):
    run = _copy(tiny_built, tmp_path / "again")
    code, _, err = run_cli("gen-trajectories", str(run), "--per-scene", "4", "--min-geodesic", "1", "--tasks", ALL,
                           "--task-episodes", "6")
    assert code == 0, err
    shards = sorted(p.name for p in (all_tasks / "episodes/tiny").glob("*.parquet"))
    assert [_sha(run / "episodes/tiny" / s) for s in shards] == [_sha(all_tasks / "episodes/tiny" / s) for s in shards]


def test_the_summary_counts_every_tasks_trajectories_and_rows(tiny_built, tmp_path, run_cli):
    """A run with tasks says how many trajectories and episode rows each task has, and totals them all (not vln's
    alone); vln alone prints as before tasks existed."""
    run = _copy(tiny_built, tmp_path / "run")
    code, out, err = run_cli("gen-trajectories", str(run), "--per-scene", "4", "--min-geodesic", "1", "--tasks", ALL,
                             "--task-episodes", "6")
    assert code == 0, err
    shards = sorted((run / "episodes/tiny").glob("*.parquet"))
    rows = pq.read_table(shards).to_pylist()
    tasks = dict.fromkeys(r["task"] for r in rows)
    ids = {t: {r["trajectory_id"] for r in rows if r["task"] == t} for t in tasks}
    lines = out.splitlines()
    assert lines[0] == (f"gen-trajectories tiny: {sum(map(len, ids.values()))} trajectories, {len(rows)} episode rows "
                        f"in {len(shards)} shard(s) -> {run / 'episodes/tiny'}")
    assert list(tasks) == ["vln", *sorted(set(tasks) - {"vln"})] and len(ids["nogoal"]) == 6
    assert "  by task: " + "; ".join(f"{t} {len(ids[t])} trajectories, {sum(r['task'] == t for r in rows)} episode "
                                     "rows" for t in tasks) in lines
    code, out, _ = run_cli("gen-trajectories", str(_copy(tiny_built, tmp_path / "vln")), "--per-scene", "4",
                           "--min-geodesic", "1")
    assert out.startswith("gen-trajectories tiny: 4 trajectories, ") and "by task" not in out


def test_the_card_lists_the_task_columns_only_for_a_run_with_tasks(all_tasks, tiny_built):
    from sagebench.episodes.card import card_text

    assert "| `goal_polar` |" in card_text(all_tasks) and "- `objectnav`: `goal_category`" in card_text(all_tasks)
    assert "goal_polar" not in card_text(tiny_built)



def test_the_goal_image_column_says_what_the_rollout_shows(all_tasks):
    """The card and the shards' schema tell both forms of goal_image, and that the rollout's own renderer draws a
    rendered one (gsplat under --renderer auto where it can run), not the CPU renderer alone."""
    from sagebench.episodes.card import card_text

    shard = sorted((all_tasks / "episodes" / "tiny").glob("part-*.parquet"))[0]
    schema = pq.read_schema(shard).field("goal_image").metadata[b"description"].decode()
    card = next(line for line in card_text(all_tasks).splitlines() if line.startswith("| `goal_image` |"))
    for text in (schema, card):
        assert "'render:'" in text and "PNG file relative to the run" in text, text
        assert "rollout's own renderer" in text and "--renderer" in text and "CPU renderer" not in text, text

def test_a_category_with_no_instance_is_refused_and_nothing_is_written(tiny_built, tmp_path, run_cli):
    run = _copy(tiny_built, tmp_path / "run")
    before = snapshot(run)
    code, _, err = run_cli("gen-trajectories", str(run), "--tasks", "objectnav", "--objectnav-categories", "piano")
    assert code == 2
    assert err.strip().splitlines() == [
        f"error: {run / 'scenes/tiny/semantic_map.json'}: --objectnav-categories: objectnav category 'piano': no "
        "instance; nothing written"]
    assert snapshot(run) == before


def test_task_options_without_a_task_are_refused(tiny_built, tmp_path, run_cli):
    run = _copy(tiny_built, tmp_path / "run")
    before = snapshot(run)
    code, _, err = run_cli("gen-trajectories", str(run), "--nogoal-budget", "60")
    assert code == 2
    assert err.strip() == "error: the task table's options are used only with --tasks other than vln"
    assert snapshot(run) == before


@pytest.mark.parametrize("column", ["goal_polar", "budget_s", "goal_viewpoints"])
def test_a_shard_whose_row_lacks_a_field_its_task_needs_is_refused_naming_file_and_field(all_tasks, tmp_path, column):
    import pyarrow as pa
    import pyarrow.compute as pc

    from sagebench.episodes.shards import read_episodes
    from sagebench.errors import DataError

    shard = sorted((all_tasks / "episodes/tiny").glob("*.parquet"))[0]
    table = pq.read_table(shard)
    i = table.column_names.index(column)
    broken = table.set_column(i, table.schema.field(i), pc.if_else(pa.array([True] * table.num_rows),
                                                                   pa.nulls(table.num_rows, table.column(i).type),
                                                                   table.column(i)))
    bad = tmp_path / shard.name
    pq.write_table(broken, bad)
    task = {"goal_polar": "pointnav", "budget_s": "nogoal", "goal_viewpoints": "objectnav"}[column]
    if task not in table.column("task").to_pylist():
        pytest.skip(f"no {task} row in the first shard")
    with pytest.raises(DataError) as err:
        read_episodes(bad)
    assert err.value.path == str(bad) and err.value.field == column
    assert f"a {task} episode needs {column}" in str(err.value)


def test_the_point_goal_is_habitats_polar_goal_counter_clockwise():
    from sagebench.episodes.tasks import pointgoal_polar

    assert pointgoal_polar(0, 0, 0, 2, 0) == pytest.approx((2, 0))  # straight ahead
    assert pointgoal_polar(0, 0, 0, 0, 1) == pytest.approx((1, math.pi / 2))  # to the left: positive
    assert pointgoal_polar(1, 1, math.pi / 2, 2, 1) == pytest.approx((1, -math.pi / 2))  # facing +Y, goal at +X: right
