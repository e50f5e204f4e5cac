"""`sagebench gen-trajectories` on the built demo scene: 200 trajectories, two instructions each, reproducible."""

import re
import shutil
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from sagebench.episodes.schema import EPISODE_SCHEMA
from sagebench.episodes.shards import read_episodes

SCENE = "demo_apartment_0"


def _run_dir(demo_built_run: Path, dest: Path) -> Path:
    shutil.copytree(demo_built_run / "scenes", dest / "scenes")
    return dest


def _files(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def generated(demo_built_run, tmp_path_factory):
    """The default command's output (module scope: run once, read by several tests)."""
    from sagebench.cli import main

    run = _run_dir(demo_built_run, tmp_path_factory.mktemp("gen"))
    with pytest.raises(SystemExit) as exc:
        main(["gen-trajectories", str(run)])
    assert exc.value.code in (0, None)
    return run


def test_default_run_writes_200_trajectories_with_low_and_high_level_instructions(generated):
    table = read_episodes(generated / "episodes" / SCENE)
    assert table.schema == EPISODE_SCHEMA
    rows = table.to_pylist()
    by_traj: dict[str, list[tuple[str, str]]] = {}
    for r in rows:
        by_traj.setdefault(r["trajectory_id"], []).append((r["instruction_level"], r["instruction_type"]))
    assert len(by_traj) == 200 and len(rows) == 600
    high = {"Add_Object", "Scenario_Driven", "Relative_Relationship", "Attribute_Based", "Area_Based"}
    for pairs in by_traj.values():
        assert pairs[:2] == [("low", "Base_Action"), ("low", "Single_Goal")]
        assert pairs[2][0] == "high" and pairs[2][1] in high
    assert len({r["episode_id"] for r in rows}) == 600
    assert {r["instruction_source"] for r in rows} == {"template"}
    assert {r["goal_radius"] for r in rows} == {1.0} and {r["seed"] for r in rows} == {0}
    assert (generated / "previews" / SCENE / "paths.png").stat().st_size > 1000
    assert pq.read_table(generated / "episodes" / SCENE).num_rows == 600  # the directory reads as one dataset
    assert {p.suffix for p in (generated / "episodes").rglob("*") if p.is_file()} == {".parquet"}  # shards only


def test_every_episode_starts_and_ends_on_navigable_cells_in_range(generated):
    with np.load(generated / "scenes" / SCENE / "topdown.npz") as npz:
        nav, res, origin = npz["navigable"], float(npz["resolution"]), npz["origin"]
    for r in read_episodes(generated / "episodes" / SCENE).to_pylist():
        path = np.array(r["reference_path"])
        cells = np.floor((path[:, :2] - origin) / res).astype(int)
        assert nav[cells[:, 1], cells[:, 0]].all()
        assert 2.0 <= r["geodesic_distance"] <= 20.0
        seg = np.diff(path[:, :2], axis=0)
        assert r["geodesic_distance"] == pytest.approx(np.hypot(seg[:, 0], seg[:, 1]).sum())
        assert r["start_position"] == path[0, :3].tolist() and r["goal_position"] == path[-1, :3].tolist()
        assert r["start_yaw"] == pytest.approx(np.arctan2(seg[0, 1], seg[0, 0]))


def test_instruction_texts_hold_no_internal_ids(generated):
    for r in read_episodes(generated / "episodes" / SCENE).to_pylist():
        text = r["instruction_text"]
        assert not re.search(r"room_\d|object:|_|#", text), text
        if r["instruction_type"] == "Single_Goal":
            assert not re.search(r"\d", text), text


def test_same_seed_gives_byte_identical_shards(run_cli, generated, tmp_path):
    run = _run_dir(generated, tmp_path)
    code, out, _ = run_cli("gen-trajectories", run, "--seed", "0")
    assert code == 0 and "200 trajectories, 600 episode rows" in out
    assert ("  high-level types: Add_Object 40/40, Scenario_Driven 40/40, Relative_Relationship 40/40, "
            "Attribute_Based 40/40, Area_Based 40/40 (chosen/quota)\n") in out
    assert _files(generated / "episodes" / SCENE) == _files(run / "episodes" / SCENE)


def test_options_shard_mb_per_scene_seed_and_none(run_cli, demo_built_run, tmp_path):
    run = _run_dir(demo_built_run, tmp_path)
    code, out, _ = run_cli("gen-trajectories", run, "--scene", SCENE, "--per-scene", "25", "--shard-mb", "0.004",
                           "--seed", "3", "--instructions", "none", "--min-geodesic", "4", "--max-geodesic", "9",
                           "--goal-radius", "0.5")
    assert code == 0
    shards = sorted((run / "episodes" / SCENE).glob("part-*.parquet"))
    assert len(shards) >= 2  # 25 bare rows are more than 4 kB
    counts = [pq.read_metadata(p).num_rows for p in shards]
    assert sum(counts) == 25 and len(set(counts[:-1])) <= 1 and counts[-1] <= counts[0]
    assert len({p.name.rsplit("-", 1)[0] for p in shards}) == 1  # the scene's one split
    rows = read_episodes(run / "episodes" / SCENE).to_pylist()
    assert {r["instruction_text"] for r in rows} == {None} and {r["seed"] for r in rows} == {3}
    assert "high-level types" not in out
    assert {r["goal_radius"] for r in rows} == {0.5} and all(4 <= r["geodesic_distance"] <= 9 for r in rows)


def test_asking_for_more_than_the_scene_allows_warns_with_the_reason(run_cli, demo_built_run, tmp_path):
    run = _run_dir(demo_built_run, tmp_path)
    code, out, err = run_cli("gen-trajectories", run, "--per-scene", "5000", "--instructions", "none")
    assert code == 0
    assert re.search(r"warning: demo_apartment_0: \d+ of 5000 trajectories: all \d+ ordered pairs of \d+ uniquely "
                     r"named targets tried \(.*shorter than min_geodesic_m", err)


@pytest.mark.parametrize("args,fragment", [
    (["--per-scene", "0"], "error: --per-scene: Input should be greater than or equal to 1"),
    (["--instructions", "gpt"], "error: --instructions: Input should be 'template', 'llm' or 'none'"),
    (["--instructions", "llm"], "error: --instructions llm needs --llm-base-url and --llm-model"),
    (["--scene", "nope"], "no scenes/nope/scene.json (scenes found: demo_apartment_0); "
                          "run `sagebench build-scene` on this run first"),
    (["--goal-radius", "0"], "error: --goal-radius: Input should be greater than 0"),
    (["--min-geodesic", "25"], "error: min_geodesic_m (25.0) must be below max_geodesic_m (20.0)"),
])
def test_bad_options_exit_2_and_write_nothing(run_cli, demo_built_run, tmp_path, args, fragment):
    run = _run_dir(demo_built_run, tmp_path)
    code, _, err = run_cli("gen-trajectories", run, *args)
    assert code == 2 and fragment in err
    assert not (run / "episodes").exists()


def test_missing_build_scene_output_exits_2(run_cli, tmp_path):
    code, _, err = run_cli("gen-trajectories", tmp_path)
    assert code == 2 and err == (f"error: {tmp_path}: no scenes/<scene_id>/scene.json (scenes found: none); "
                                 f"run `sagebench build-scene` on this run first\n")


def test_corrupt_topdown_map_exits_2_and_keeps_earlier_episodes(run_cli, demo_built_run, tmp_path):
    run = _run_dir(demo_built_run, tmp_path)
    assert run_cli("gen-trajectories", run, "--per-scene", "3")[0] == 0
    before = _files(run / "episodes" / SCENE)
    npz = run / "scenes" / SCENE / "topdown.npz"
    with np.load(npz) as data:
        arrays = {k: data[k] for k in data.files if k != "navigable"}
    np.savez(npz, **arrays)
    code, _, err = run_cli("gen-trajectories", run)
    assert code == 2 and f"error: {npz}: navigable: array missing" in err
    assert _files(run / "episodes" / SCENE) == before
