"""`sagebench evaluate` on a small demo run: the oracle scores perfectly, a path through walls collides,
missing/unknown/duplicate episodes and malformed lines are errors that name their line and write nothing."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from sagebench.episodes.load import load_episodes

SCENE = "demo_apartment_0"
HEADER = ("group                            EPISODES       SR      OSR      SPL       NE   NE_STR     NDTW     SDTW"
          "      CSR      ICP       PS      LEN")
DISTANCES = "distance to the goal: on foot for SR, OSR, SPL, NE, SDTW; straight for NE_STR"


@pytest.fixture(scope="module")
def oracle(demo_eval_run, tmp_path_factory) -> Path:
    """Predictions of an agent that walks every reference path exactly, from station to station (the points
    every 0.25 m of arc and the corners), facing the next, with its own c(t) of 0: self-reported."""
    from sagebench.navsim.policies import oracle_targets

    rows = []
    for e in load_episodes(demo_eval_run):
        xy = oracle_targets(e.reference_path, 0.25)
        yaw = np.append(np.arctan2(*np.diff(xy, axis=0).T[::-1]), 0.0)
        yaw[0], yaw[-1] = e.start_yaw, yaw[-2] if len(yaw) > 1 else e.start_yaw
        poses = [[float(x), float(y), float(e.start[2]), float(a)] for (x, y), a in zip(xy, yaw)]
        rows.append({"episode_id": e.episode_id, "poses": poses, "stopped": True,
                     "collision_intensity": [0.0] * len(poses)})
    return _write(tmp_path_factory.mktemp("oracle") / "oracle.jsonl", rows)


def _lines(path: Path) -> list[dict]:
    return [json.loads(t) for t in path.read_text().splitlines()]


def _write(path: Path, rows: list[dict]) -> Path:
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    return path


def test_the_oracle_scores_perfectly(demo_eval_run, oracle, tmp_path, run_cli):
    out = tmp_path / "results.json"
    code, stdout, err = run_cli("evaluate", "--run", demo_eval_run, "--predictions", oracle, "--out", out)
    assert code == 0, err
    lines = stdout.splitlines()
    n = len(_lines(oracle))
    assert lines[0] == HEADER
    assert lines[1].startswith(f"overall                          {n:>8d}    1.000    1.000")
    groups = [ln.split()[0] for ln in lines[2:-4]]
    assert groups == sorted(groups, key=("level", "type", "split").index) and lines[-1] == f"wrote {out}"  # levels, then types
    assert lines[-4] == DISTANCES
    assert lines[-3].startswith(f"ICP from c(t) self-reported in {n} episodes (measured: ")  # the baseline's own
    assert lines[-2] == "observations: not recorded (predictions without a rollout record)"
    res = json.loads(out.read_text())
    o = res["overall"]
    assert (o["episodes"], o["sr"], o["osr"], o["csr"], o["icp"]) == (n, 1.0, 1.0, 1.0, 0.0)
    assert o["spl"] == pytest.approx(1.0, abs=1e-5) and o["ndtw"] == pytest.approx(0.99735, abs=2e-4)  # measured
    assert res["missing"] == [] and res["intensity_replayed"] == 0 and len(res["per_episode"]) == n
    assert res["icp_source"] == {"measured": 0, "self-reported": n, "derived": 0}
    assert res["predictions"]["file"] == "oracle.jsonl" and res["config"]["metrics"]["corridor_radius"] == 1.0
    assert set(res["by_type"]) >= {"Base_Action", "Single_Goal"} and set(res["by_level"]) >= {"low"}
    assert sum(g["episodes"] for g in res["by_type"].values()) == n
    assert sum(g["episodes"] for g in res["by_level"].values()) == n
    assert len(lines) == 1 + 1 + len(res["by_level"]) + len(res["by_type"]) + len(res["by_split"]) + 4
    assert res["by_split"] == {"val_unseen": res["overall"]}  # the demo scene, held out at the default fractions
    assert res["distance_used"]["sr"] == "on_foot" and res["distance_used"]["ne_straight"] == "straight"
    first = out.read_bytes()
    assert run_cli("evaluate", "--run", demo_eval_run, "--predictions", oracle, "--out", out)[0] == 0
    assert out.read_bytes() == first


def test_poses_alone_are_replayed_for_collision_intensity(demo_eval_run, oracle, tmp_path, run_cli):
    rows = [{k: v for k, v in r.items() if k not in ("collision_intensity", "intensity_source")} for r in _lines(oracle)]
    # the first episode's agent heads 30 m straight on: out through the apartment's walls (it is 12 m across)
    first = rows[0]
    x, y, z, yaw = first["poses"][0]
    first["poses"] = [[x, y, z, yaw], [x + 30 * math.cos(yaw), y + 30 * math.sin(yaw), z, yaw]]
    pred = _write(tmp_path / "poses.jsonl", rows)
    out = tmp_path / "r.json"
    assert run_cli("evaluate", "--run", demo_eval_run, "--predictions", pred, "--out", out)[0] == 0
    res = json.loads(out.read_text())
    assert res["intensity_replayed"] == len(rows)
    assert {e["icp_source"] for e in res["per_episode"]} == {"derived"}
    icp = {e["episode_id"]: e["icp"] for e in res["per_episode"]}
    assert icp.pop(first["episode_id"]) > 0.3  # c of the step >= 1 - 12/30, and ICP its mean with c(0) = 0
    assert set(icp.values()) == {0.0}  # the oracle's own poses replay without collisions


def test_missing_episodes_are_an_error_unless_allowed(demo_eval_run, oracle, tmp_path, run_cli):
    rows = _lines(oracle)
    n = len(rows)
    dropped = sorted(r["episode_id"] for r in rows[:2])
    pred = _write(tmp_path / "part.jsonl", rows[2:])
    out = tmp_path / "r.json"
    code, _, err = run_cli("evaluate", "--run", demo_eval_run, "--predictions", pred, "--out", out)
    assert code == 2 and not out.exists()
    assert err.strip() == (f"error: {pred}: 2 of {n} episodes have no prediction ({dropped[0]}, {dropped[1]}); "
                           "pass --allow-missing to score them as failures")
    code, stdout, _ = run_cli("evaluate", "--run", demo_eval_run, "--predictions", pred, "--out", out, "--allow-missing")
    assert code == 0 and "2 episodes had no prediction and were scored as failures" in stdout
    res = json.loads(out.read_text())
    assert res["missing"] == dropped
    assert res["overall"]["sr"] == pytest.approx((n - 2) / n, abs=1e-6)
    assert res["overall"]["icp"] == pytest.approx(2 / n, abs=1e-6)  # missing: ICP 1, every other metric 0
    # a missing episode's NE is the farthest walk from its goal, never less than the walk from its start
    geodesic = {e.episode_id: e.geodesic_distance for e in load_episodes(demo_eval_run)}
    for row in (r for r in res["per_episode"] if r["missing"]):
        assert row["ne"] >= geodesic[row["episode_id"]] - 1e-6


@pytest.mark.parametrize("edit, message", [
    (lambda rows: rows + [rows[0]], "{pred}:{n1}: episode_id: duplicate episode id '{id0}' (first on line 1)"),
    (lambda rows: [rows[0] | {"episode_id": "nope"}] + rows[1:],
     "{pred}:1: episode_id: unknown episode id 'nope': not an episode being evaluated (1 unknown in all)"),
    (lambda rows: [rows[0] | {"poses": [[p[0] + 0.5, p[1], p[2], p[3]] for p in rows[0]["poses"]]}] + rows[1:],
     "{pred}:1: poses[0]: the first pose is 0.500 m from the episode's start_position (more than 0.1 m)"),
    (lambda rows: [rows[0] | {"collision_intensity": [0.0]}] + rows[1:],
     "{pred}:1: collision_intensity has 1 values for {t0} poses (one per pose)"),
    (lambda rows: [rows[0] | {"stopped": "yes"}] + rows[1:], "{pred}:1: stopped: Input should be a valid boolean"),
])
def test_bad_predictions_are_exit_2_and_write_nothing(demo_eval_run, oracle, tmp_path, run_cli, edit, message):
    rows = _lines(oracle)
    pred = _write(tmp_path / "bad.jsonl", edit(rows))
    out = tmp_path / "r.json"
    code, stdout, err = run_cli("evaluate", "--run", demo_eval_run, "--predictions", pred, "--out", out)
    assert code == 2 and stdout == "" and not out.exists()
    assert err.strip() == "error: " + message.format(pred=pred, n1=len(rows) + 1, id0=rows[0]["episode_id"],
                                                     t0=len(rows[0]["poses"]))


def test_intensity_replay_needs_scene_xml_but_given_intensities_do_not(demo_eval_run, oracle, tmp_path, run_cli):
    run = tmp_path / "run"
    shutil.copytree(demo_eval_run, run)
    (run / "scenes" / SCENE / "scene.xml").unlink()
    assert run_cli("evaluate", "--run", run, "--predictions", oracle)[0] == 0
    rows = [{k: v for k, v in r.items() if k not in ("collision_intensity", "intensity_source")} for r in _lines(oracle)]
    pred = _write(tmp_path / "poses.jsonl", rows)
    code, _, err = run_cli("evaluate", "--run", run, "--predictions", pred)
    assert code == 2
    assert err.strip() == f"error: {run / 'scenes' / SCENE / 'scene.xml'}: missing; run `sagebench export-usd` on this run first"


@pytest.mark.parametrize("args, message", [
    (["--scene", "nope"], "no episodes/nope/part-*.parquet (scenes found: demo_apartment_0); "
                          "run `sagebench gen-trajectories` on this run first"),
    (["--workers", "0"], "error: --workers: Input should be greater than or equal to 1"),
    (["--start-tolerance", "0"], "error: --start-tolerance: Input should be greater than 0"),
])
def test_bad_options_are_exit_2(demo_eval_run, oracle, run_cli, args, message):
    code, _, err = run_cli("evaluate", "--run", demo_eval_run, "--predictions", oracle, *args)
    assert code == 2 and message in err


def test_absent_predictions_file_is_exit_2(demo_eval_run, tmp_path, run_cli):
    code, _, err = run_cli("evaluate", "--run", demo_eval_run, "--predictions", tmp_path / "none.jsonl")
    assert code == 2 and err.strip() == f"error: {tmp_path / 'none.jsonl'}: does not exist"


def test_splits_are_scored_apart_and_predictions_of_other_splits_are_left_out(demo_built_run, tmp_path, run_cli):
    from sagebench.settings.gen_trajectories import GenTrajectoriesConfig, SplitConfig
    from sagebench.stages.gen_trajectories import gen_trajectories

    run = tmp_path / "run"
    shutil.copytree(demo_built_run / "scenes", run / "scenes")
    gen_trajectories(run, GenTrajectoriesConfig(per_scene=8, seed=0, instructions="none",
                                                splits=SplitConfig(val_unseen=0, test=0, val_seen=0.25)))
    episodes = load_episodes(run)
    assert sorted(e.split for e in episodes) == ["train"] * 6 + ["val_seen"] * 2
    # the reference path followed exactly, for every episode of both splits
    pred = _write(tmp_path / "p.jsonl", [{"episode_id": e.episode_id, "poses": e.reference_path.tolist(),
                                          "stopped": True, "collision_intensity": [0.0] * len(e.reference_path)}
                                         for e in episodes])
    out = tmp_path / "r.json"
    code, stdout, err = run_cli("evaluate", "--run", run, "--predictions", pred, "--out", out, "--split", "val_seen")
    assert code == 0, err
    res = json.loads(out.read_text())
    assert res["split"] == "val_seen" and res["episodes"] == 2 and list(res["by_split"]) == ["val_seen"]
    assert {r["episode_id"] for r in res["per_episode"]} == {e.episode_id for e in episodes if e.split == "val_seen"}
    code, stdout, _ = run_cli("evaluate", "--run", run, "--predictions", pred, "--out", out)
    res = json.loads(out.read_text())
    assert {k: v["episodes"] for k, v in res["by_split"].items()} == {"train": 6, "val_seen": 2}
    assert [ln.split()[:3] for ln in stdout.splitlines() if ln.startswith("split ")] == [
        ["split", "train", "6"], ["split", "val_seen", "2"]]
    code, _, err = run_cli("evaluate", "--run", run, "--predictions", pred, "--split", "test")
    assert code == 2 and err.strip() == f"error: {run}: no episodes in split 'test'"
    code, _, err = run_cli("evaluate", "--run", run, "--predictions", pred, "--split", "dev")
    assert code == 2 and "'dev' is not a split (one of train, val_seen, val_unseen, test, trajectory_unseen, instruction_unseen)" in err


def test_traces_that_scraped_walls_get_a_derived_icp_well_above_0(demo_eval_run, tmp_path, run_cli):
    from sagebench.stages.rollout import BaselineConfig, run_baseline

    own = tmp_path / "straight.jsonl"
    run_baseline(demo_eval_run, own, BaselineConfig(agent_name="straight"))
    rows = _lines(own)
    bare = _write(tmp_path / "bare.jsonl",
                  [{k: v for k, v in r.items() if k not in ("collision_intensity", "intensity_source")} for r in rows])
    measured, out = tmp_path / "m.json", tmp_path / "r.json"
    assert run_cli("evaluate", "--run", demo_eval_run, "--predictions", own, "--out", measured)[0] == 0
    code, stdout, _ = run_cli("evaluate", "--run", demo_eval_run, "--predictions", bare, "--out", out)
    assert code == 0
    res = json.loads(out.read_text())
    assert res["icp_source"]["derived"] == len(rows)
    # derived 0.089 against the simulator's measured 0.099 for the same traces; replaying reached poses alone
    # gave 0.00, contact within 1 cm finds the scraping
    sim = json.loads(measured.read_text())["overall"]["icp"]
    assert res["overall"]["icp"] >= 0.75 * sim and sim > 0.05
    assert f"ICP from c(t) derived in {len(rows)} episodes" in stdout and "within 0.01 m of a collider" in stdout


def _hashes(root: Path) -> dict[str, str]:
    """sha256 of every file under `root` by relative path (the lock file left out)."""
    import hashlib

    return {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file() and p.name != ".sagebench.lock"}


def _contact_pixels(png: Path, map_rows: int) -> int:
    """Pixels of the contact colour on the map part of an episode picture (the legend has a swatch of it too)."""
    import cv2

    from sagebench.episodes.picture import CONTACT, HEADER_PX

    img = cv2.cvtColor(cv2.imread(str(png)), cv2.COLOR_BGR2RGB)[HEADER_PX:HEADER_PX + map_rows]
    return int((img == np.array(CONTACT, np.uint8)).all(axis=2).sum())


def test_visualize_draws_each_scored_episode_with_its_contact_steps(demo_eval_run, oracle, tmp_path, run_cli):
    from sagebench.episodes.picture import scale_for
    from sagebench.evaluation.pictures import MAX_SIZE_PX
    from sagebench.topdown.grid_file import read_topdown_grids

    rows = _lines(oracle)
    # the first episode's agent touched something at its second pose; the others never did
    bumped = rows[0] | {"collision_intensity": [0.0, 0.6] + [0.0] * (len(rows[0]["poses"]) - 2)}
    pred = _write(tmp_path / "agent.jsonl", [bumped, *rows[1:]])
    pics = tmp_path / "pictures"
    code, stdout, err = run_cli("evaluate", "--run", demo_eval_run, "--predictions", pred, "--visualize", pics)
    assert code == 0, err
    assert stdout.splitlines()[-1] == f"wrote {len(rows)} pictures into {pics}"
    index = json.loads((pics / "pictures.json").read_text())
    assert index["predictions"]["file"] == "agent.jsonl"
    assert index["pictures"] == {r["episode_id"]: f"trajectory_visualization_{SCENE}_{r['episode_id']}.png"
                                 for r in rows}
    assert sorted(p.name for p in pics.iterdir() if not p.name.startswith(".")) == sorted(
        [*index["pictures"].values(), "pictures.json"])
    shape = read_topdown_grids(demo_eval_run / "scenes" / SCENE / "topdown.npz").navigable.shape
    map_rows = shape[0] * scale_for(shape, MAX_SIZE_PX)
    red = {eid: _contact_pixels(pics / name, map_rows) for eid, name in index["pictures"].items()}
    assert red.pop(rows[0]["episode_id"]) > 20 and set(red.values()) == {0}
    before = _hashes(pics)
    assert run_cli("evaluate", "--run", demo_eval_run, "--predictions", pred, "--visualize", pics)[0] == 0
    assert _hashes(pics) == before  # an earlier --visualize output is written again, the same bytes


def test_visualize_again_removes_only_the_pictures_it_drew_before(demo_eval_run, oracle, tmp_path, run_cli):
    pics = tmp_path / "pictures"
    pics.mkdir()
    gone = "trajectory_visualization_other_0123.png"
    (pics / "pictures.json").write_text(json.dumps({"pictures": {"0123": gone, "x": "../outside.png"}}))
    for name in (gone, "notes.txt"):
        (pics / name).write_text("earlier")
    (tmp_path / "outside.png").write_text("the user's")
    assert run_cli("evaluate", "--run", demo_eval_run, "--predictions", oracle, "--visualize", pics)[0] == 0
    assert not (pics / gone).exists() and (pics / "notes.txt").read_text() == "earlier"
    assert (tmp_path / "outside.png").read_text() == "the user's"
    assert len(list(pics.glob("trajectory_visualization_*.png"))) == len(_lines(oracle))


@pytest.mark.parametrize("where, message", [
    ("run/pictures", "error: --visualize: {pics} lies inside the run {run}: give a folder outside it"),
    ("mine", "error: --visualize: {pics} is not empty and holds no evaluate --visualize output; use a new "
             "--visualize"),
])
def test_visualize_refuses_a_folder_it_may_not_write_and_writes_nothing(demo_eval_run, oracle, tmp_path, run_cli,
                                                                         where, message):
    run = tmp_path / "run"
    shutil.copytree(demo_eval_run, run)
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "thesis.tex").write_text("the user's")
    pics, out = tmp_path / where, tmp_path / "r.json"
    before = _hashes(tmp_path)
    code, stdout, err = run_cli("evaluate", "--run", run, "--predictions", oracle, "--out", out, "--visualize", pics)
    assert (code, stdout) == (2, "") and err == message.format(pics=pics, run=run) + "\n"
    assert _hashes(tmp_path) == before and not out.exists() and (where == "mine") == pics.exists()


def test_bad_predictions_with_visualize_create_no_folder(demo_eval_run, oracle, tmp_path, run_cli):
    pred = _write(tmp_path / "bad.jsonl", _lines(oracle)[1:])  # an episode without a prediction
    code, _, err = run_cli("evaluate", "--run", demo_eval_run, "--predictions", pred, "--visualize", tmp_path / "p")
    assert code == 2 and "pass --allow-missing" in err and not (tmp_path / "p").exists()
