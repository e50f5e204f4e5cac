"""`sagebench validate` on the demo apartment: clean paths pass; a path through a wall, a shifted Gaussian
layer and bad input fail the way the user is told they do."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

SCENE = "demo_apartment_0"


@pytest.fixture(scope="module")
def validated_run(demo_built_run, tmp_path_factory) -> Path:
    """The demo run with 20 trajectories and scene.xml; read-only for the tests (copy before changing)."""
    from sagebench.stages.export_usd import export_usd
    from sagebench.stages.gen_trajectories import GenTrajectoriesConfig, gen_trajectories

    run = tmp_path_factory.mktemp("validate_run")
    shutil.copytree(demo_built_run / "scenes", run / "scenes")
    gen_trajectories(run, GenTrajectoriesConfig(per_scene=20, seed=0))
    export_usd(run, cache_dir=tmp_path_factory.mktemp("coacd_cache"))
    return run


def _copy(run: Path, tmp_path: Path) -> Path:
    out = tmp_path / "run"
    shutil.copytree(run, out, ignore=shutil.ignore_patterns("validation", "reports"))
    return out


def test_demo_trajectories_all_pass(validated_run, tmp_path, run_cli):
    run = _copy(validated_run, tmp_path)
    code, out, err = run_cli("validate", run, "--frames-per-scene", "2")
    assert code == 0, out + err
    assert f"validate {SCENE}: 20/20 trajectories pass" in out and "alignment ok on 6 frames" in out
    vdir = run / "validation" / SCENE
    assert sorted(p.name for p in vdir.iterdir()) == ["part-00000.parquet"]  # Parquet only: one table to readers
    table = pq.read_table(vdir / "part-00000.parquet")
    assert table.num_rows == 20
    assert all(table.column("passed").to_pylist())
    assert min(table.column("csr").to_pylist()) == 1.0
    assert max(table.column("icp").to_pylist()) < 0.05  # brushes within map precision only
    episodes = pq.read_table(run / "episodes" / SCENE)
    assert sorted(sum(table.column("episode_ids").to_pylist(), [])) == sorted(episodes.column("episode_id").to_pylist())
    report = json.loads((run / "reports" / SCENE / "report.json").read_text())
    assert report["trajectories"] == 20 and report["failed"] == 0 and report["episodes"] == episodes.num_rows
    assert report["failures_by_reason"] == {"collision": 0, "goal_not_reached": 0, "left_corridor": 0, "incomplete": 0,
                                            "instruction_not_executable": 0}
    assert report["metrics"]["csr"]["min"] == 1.0
    assert len(report["alignment"]["frames"]) == 6
    assert all(f["median_abs_diff"] < 0.10 for f in report["alignment"]["frames"])
    frames = sorted(p.name for p in (run / "reports" / SCENE / "frames").iterdir())
    assert "contact_sheet.png" in frames and len(frames) == 1 + 6 * 2  # RGB and instance ids per frame
    # same inputs, same bytes
    first = {p: p.read_bytes() for p in (vdir / "part-00000.parquet", run / "reports" / SCENE / "report.json")}
    assert run_cli("validate", run, "--frames-per-scene", "2")[0] == 0
    assert all(p.read_bytes() == b for p, b in first.items())


def test_the_replay_agent_is_the_body_the_map_was_built_for(validated_run, tmp_path):
    """Radius, clearance and height come from semantic_map.json (build-scene's record of the run's agent), not from
    a default: a map built for a wider, taller agent that rides higher gets that agent in the replay."""
    from sagebench.replay.physics import AGENT_GEOM
    from sagebench.replay.scene_model import open_replay_model
    from sagebench.settings.shared import AgentConfig, ReplayConfig

    run = tmp_path / "run"
    shutil.copytree(validated_run / "scenes", run / "scenes")
    assert open_replay_model(run, SCENE, replay=ReplayConfig()).agent == AgentConfig()
    smap = run / "scenes" / SCENE / "semantic_map.json"
    data = json.loads(smap.read_text())
    data |= {"agent_radius": 0.3, "band_m": [data["floor_height"] + 0.1, data["floor_height"] + 1.6]}
    smap.write_text(json.dumps(data))
    rm = open_replay_model(run, SCENE, replay=ReplayConfig())
    assert rm.agent == AgentConfig(radius=0.3, clearance=0.1, height=1.6)
    mesh = rm.model.geom(AGENT_GEOM).dataid[0]
    adr, n = rm.model.mesh_vertadr[mesh], rm.model.mesh_vertnum[mesh]
    body = rm.model.mesh_vert[adr:adr + n]  # the prism, centred by MuJoCo on its own frame
    assert np.ptp(body[:, 2]) == pytest.approx(1.5, abs=1e-6) and np.ptp(body[:, 0]) >= 0.6


def test_a_path_through_a_wall_fails_with_collision(validated_run, tmp_path, run_cli):
    run = _copy(validated_run, tmp_path)
    (shard,) = (run / "episodes" / SCENE).glob("part-*.parquet")
    table = pq.read_table(shard)
    rows = table.to_pylist()
    bad = rows[0]["trajectory_id"]
    # straight from the start across the whole apartment: through walls
    start = rows[0]["reference_path"][0]
    path = [start, [start[0] + 8.0 if start[0] < 6 else start[0] - 8.0, start[1], start[2], start[3]]]
    for r in rows:
        if r["trajectory_id"] == bad:
            r["reference_path"] = path
            r["goal_position"] = path[-1][:3]
    pq.write_table(pa.Table.from_pylist(rows, schema=table.schema), shard)
    code, out, _ = run_cli("validate", run, "--frames-per-scene", "0")
    assert code == 1
    assert "19/20 trajectories pass" in out
    assert f"FAIL {SCENE} {bad}: collision, goal_not_reached, instruction_not_executable" in out
    report = json.loads((run / "reports" / SCENE / "report.json").read_text())
    assert report["failures_by_reason"]["collision"] == 1
    assert report["failures"][0]["trajectory_id"] == bad


def test_a_base_action_sentence_that_misses_the_goal_fails_as_not_executable(validated_run, tmp_path, run_cli):
    run = _copy(validated_run, tmp_path)
    (shard,) = (run / "episodes" / SCENE).glob("part-*.parquet")
    table = pq.read_table(shard)
    rows = table.to_pylist()
    row = next(r for r in rows if r["instruction_type"] == "Base_Action")
    row["instruction_text"] = "Turn around and walk forward 1 metre, then stop."  # the path itself is untouched
    pq.write_table(pa.Table.from_pylist(rows, schema=table.schema), shard)
    code, out, _ = run_cli("validate", run, "--frames-per-scene", "0")
    assert code == 1
    assert "19/20 trajectories pass" in out
    assert f"FAIL {SCENE} {row['trajectory_id']}: instruction_not_executable" in out
    report = json.loads((run / "reports" / SCENE / "report.json").read_text())
    assert report["failures_by_reason"]["instruction_not_executable"] == 1


def test_shifted_gaussians_fail_the_alignment(validated_run, tmp_path, run_cli):
    from sagebench.render.gaussians import Gaussians
    from sagebench.splats.ply import read_ply, write_ply

    run = _copy(validated_run, tmp_path)
    ply = run / "scenes" / SCENE / "gaussians.ply"
    g = read_ply(ply)
    write_ply(ply, Gaussians(g.means + np.float32([0.3, 0.3, 0.0]), g.quats_wxyz, g.log_scales,
                             g.opacity_logits, g.sh, g.instance_id))
    code, out, _ = run_cli("validate", run, "--frames-per-scene", "2")
    assert code == 1
    assert "alignment FAILED on 6 frames" in out and "median depth difference" in out
    report = json.loads((run / "reports" / SCENE / "report.json").read_text())
    assert report["alignment"]["ok"] is False and report["failed"] == 0  # the paths themselves are fine


def test_no_gaussians_to_compare_fail_the_alignment(validated_run, tmp_path, run_cli):
    # an empty gaussians.ply renders nothing: 0 compared pixels must fail, not pass with a NaN median
    from sagebench.render.gaussians import Gaussians
    from sagebench.splats.ply import read_ply, write_ply

    run = _copy(validated_run, tmp_path)
    ply = run / "scenes" / SCENE / "gaussians.ply"
    g = read_ply(ply)
    write_ply(ply, Gaussians(g.means[:0], g.quats_wxyz[:0], g.log_scales[:0], g.opacity_logits[:0], g.sh[:0],
                             g.instance_id[:0]))
    code, out, _ = run_cli("validate", run, "--frames-per-scene", "1")
    assert code == 1
    assert "alignment FAILED on 3 frames" in out
    assert (f"  FAIL {SCENE} frames/" in out and "_start.png: 0 of 1200 sampled pixels compared, fewer than the "
            "minimum 300 (0.25 of them): nothing to align with" in out), out
    report = json.loads((run / "reports" / SCENE / "report.json").read_text())
    assert report["alignment"]["ok"] is False and report["alignment"]["min_compared_fraction"] == 0.25
    assert [f["compared_pixels"] for f in report["alignment"]["frames"]] == [0, 0, 0]


def test_missing_mjcf_is_exit_2_and_writes_nothing(validated_run, tmp_path, run_cli):
    run = _copy(validated_run, tmp_path)
    (run / "scenes" / SCENE / "scene.xml").unlink()
    code, out, err = run_cli("validate", run)
    assert code == 2
    assert err.strip() == f"error: {run / 'scenes' / SCENE / 'scene.xml'}: missing; run `sagebench export-usd` on this run first"
    assert not (run / "validation").exists()


@pytest.mark.parametrize("args, message", [
    (["--frames-per-scene", "-1"], "error: --frames-per-scene: Input should be greater than or equal to 0"),
    (["--depth-tolerance", "0"], "error: --depth-tolerance: Input should be greater than 0"),
    (["--scene", "nope"], "no episodes/nope/part-*.parquet (scenes found: demo_apartment_0); "
                          "run `sagebench gen-trajectories` on this run first"),
])
def test_bad_options_are_exit_2(validated_run, tmp_path, run_cli, args, message):
    run = _copy(validated_run, tmp_path)
    code, _, err = run_cli("validate", run, *args)
    assert code == 2 and message in err
    assert not (run / "validation").exists()


def test_help_says_what_it_reads_and_writes(run_cli):
    code, out, _ = run_cli("validate", "--help")
    assert code == 0
    assert "Reads" in out and "report.json" in out and "Exit status 1" in out
