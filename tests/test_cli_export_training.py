"""`sagebench export-training`: WebDataset shards of executed reference-path actions and the views before each,
loadable with `datasets`, deterministic whatever the batch, resumable after kill -9, bad input refused."""

from __future__ import annotations

import dataclasses
import io
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tarfile
import time
from pathlib import Path

import numpy as np
import pytest

from sagebench.render.observations import to_uint8
from sagebench.render.camera import agent_camera
from sagebench.render.chunks import pack
from sagebench.render.splat_render import render_packed
from sagebench.splats.ply import read_ply
from sagebench.training.actions import path_actions

SMALL = ("--width", "32", "--height", "24", "--episodes-per-shard", "4")


@pytest.fixture(scope="module")
def run(demo_eval_run, tmp_path_factory) -> Path:
    """The eval run's first eight episodes (two shards of four)."""
    import pyarrow.parquet as pq

    run = tmp_path_factory.mktemp("train_run")
    shutil.copytree(demo_eval_run / "scenes", run / "scenes")
    for part in sorted((demo_eval_run / "episodes").rglob("*.parquet")):
        dest = run / part.relative_to(demo_eval_run)
        dest.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(pq.read_table(part).slice(0, 8), dest)
        break
    return run


@pytest.fixture(scope="module")
def exported(run, tmp_path_factory) -> Path:
    from sagebench.cli import main

    out = tmp_path_factory.mktemp("export") / "train"
    with pytest.raises(SystemExit) as exc:
        main(["-q", "export-training", str(run), "--out", str(out), "--depth", "--renderer", "cpu", *SMALL])
    assert exc.value.code in (0, None)
    return out


def _members(shard: Path) -> dict[str, bytes]:
    with tarfile.open(shard) as tar:
        return {m.name: tar.extractfile(m).read() for m in tar.getmembers()}


def _samples(out: Path) -> list[dict]:
    rows = []
    for shard in sorted((out / "shards").glob("*.tar")):
        files = _members(shard)
        for name in sorted(n for n in files if n.endswith(".json")):
            key = name.removesuffix(".json")
            rows.append({"key": key, **json.loads(files[name]), "rgb": files[f"{key}.rgb.png"],
                         "depth": files.get(f"{key}.depth.png")})
    return rows


def test_layout_and_index(exported):
    index = json.loads((exported / "index.json").read_text())
    settings = json.loads((exported / "export.json").read_text())
    assert {k: index[k] for k in settings} == settings and settings["format"] == "sagebench-training-webdataset/1"
    assert index["episodes"] == 8 and [s["episodes"] for s in index["shards"]] == [4, 4]
    assert [Path(s["file"]).name for s in index["shards"]] == sorted(p.name for p in (exported / "shards").iterdir())
    assert sum(s["samples"] for s in index["shards"]) == index["samples"] == len(_samples(exported))


def test_each_episode_executes_its_derived_actions_and_sees_each_pose(exported, run):
    """Every episode's samples carry the actions derived from its reference path, in order, ending with STOP;
    sample k's view is the CPU renderer's frame at the pose the simulator reached after action k - 1 (the
    start pose for k = 0), and its depth PNG holds that frame's depth in millimetres."""
    from sagebench.navsim.simulator import Simulator

    sim = Simulator(run)
    rows = _samples(exported)
    by_episode: dict[str, list[dict]] = {}
    for r in rows:
        by_episode.setdefault(r["episode_id"], []).append(r)
    assert len(by_episode) == 8
    packed = pack(read_ply(run / "scenes" / "demo_apartment_0" / "gaussians.ply"))
    import cv2

    for eid, samples in by_episode.items():
        e = sim.episodes[eid]
        assert [s["step"] for s in samples] == list(range(len(samples)))
        assert [s["action"] for s in samples] == [int(a) for a in path_actions(e.reference_path, e.start_yaw)]
        assert samples[-1]["action_name"] == "STOP" and samples[0]["instruction"] == sim.instructions[eid]
        assert samples[0]["pose"][:2] == pytest.approx(list(e.start[:2]), abs=1e-6)
        for s in (samples[0], samples[len(samples) // 2]):
            x, y, z, yaw = s["pose"]
            cam = agent_camera(x, y, yaw, floor_z=z, width=32, height=24)
            (frame,) = render_packed(packed, [cam])
            png = cv2.imdecode(np.frombuffer(s["rgb"], np.uint8), cv2.IMREAD_COLOR)[:, :, ::-1]
            assert np.array_equal(png, to_uint8(frame.rgb))
            depth = cv2.imdecode(np.frombuffer(s["depth"], np.uint8), cv2.IMREAD_UNCHANGED)
            assert depth.dtype == np.uint16 and np.abs(depth / 1000.0 - frame.depth).max() <= 0.0005 + 1e-6


def test_datasets_loads_the_shards(exported):
    datasets = pytest.importorskip("datasets")
    ds = datasets.load_dataset("webdataset", data_files={"train": str(exported / "shards" / "*.tar")},
                               split="train")
    assert len(ds) == json.loads((exported / "index.json").read_text())["samples"]
    row = ds[0]
    assert row["rgb.png"].size == (32, 24) and row["json"]["step"] == 0 and row["json"]["action_name"]
    assert np.asarray(row["depth.png"]).dtype in (np.uint16, np.int32)


def test_same_bytes_whatever_the_batch(exported, run, tmp_path, run_cli):
    code, out, err = run_cli("-q", "export-training", run, "--out", tmp_path / "b", "--depth", "--renderer", "cpu",
                             "--batch", "3", "--workers", "1", *SMALL)
    assert code == 0, err
    for shard in sorted((exported / "shards").iterdir()):
        assert (tmp_path / "b" / "shards" / shard.name).read_bytes() == shard.read_bytes()


def test_resumes_after_kill_9_to_the_same_bytes(exported, run, tmp_path):
    """Killed once the first shard is written, a rerun leaves no temporary, keeps that shard and writes the
    rest: the same bytes as an export never interrupted."""
    out = tmp_path / "k"
    cmd = [sys.executable, "-m", "sagebench", "-q", "export-training", str(run), "--out", str(out), "--depth",
           "--renderer", "cpu", "--batch", "1", *SMALL]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    first = out / json.loads((exported / "index.json").read_text())["shards"][0]["file"]
    deadline = time.monotonic() + 600
    while not first.exists() and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert first.exists() and not (out / "index.json").exists()
    kept = first.stat().st_mtime_ns
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert first.stat().st_mtime_ns == kept
    assert sorted(p.name for p in (out / "shards").iterdir()) == sorted(p.name for p in (exported / "shards").iterdir())
    for shard in (exported / "shards").iterdir():
        assert (out / "shards" / shard.name).read_bytes() == shard.read_bytes()
    assert (out / "index.json").read_bytes() == (exported / "index.json").read_bytes()


@pytest.mark.parametrize(("args", "message"), [
    (["--split", "nope"], "error: --split: 'nope' is not one of train, val_seen, val_unseen, test, trajectory_unseen, "
                           "instruction_unseen"),
    (["--split", "test"], "error: --split: no episodes of split 'test' in {run}"),
    (["--width", "4"], "error: --width: Input should be greater than or equal to 8"),
])
def test_bad_options_are_one_line_and_write_nothing(run, tmp_path, run_cli, args, message):
    code, _, err = run_cli("export-training", run, "--out", tmp_path / "o", *args)
    assert (code, err.strip()) == (2, message.format(run=run))
    assert not (tmp_path / "o").exists()


def test_an_out_dir_of_other_settings_or_content_is_refused(exported, run, tmp_path, run_cli):
    shutil.copytree(exported, tmp_path / "e")
    code, _, err = run_cli("export-training", run, "--out", tmp_path / "e", "--renderer", "cpu", *SMALL)  # no depth
    assert code == 2 and err.strip() == (f"error: --out: {tmp_path / 'e'} holds an export of other settings or "
                                         "inputs; use a new --out or remove it")
    (tmp_path / "x").mkdir()
    (tmp_path / "x" / "notes.txt").write_text("mine")
    code, _, err = run_cli("export-training", run, "--out", tmp_path / "x", *SMALL)
    assert code == 2 and err.strip() == (f"error: --out: {tmp_path / 'x'} is not empty and holds no "
                                         "export-training output; use a new --out")
    assert sorted(p.name for p in (tmp_path / "x").iterdir()) == ["notes.txt"]


def _retrained(run: Path, tmp_path: Path) -> Path:
    """A copy of the run whose scene's Gaussians were trained again (every opacity a little lower)."""
    from sagebench.splats.ply import write_ply

    changed = tmp_path / "retrained"
    shutil.copytree(run, changed)
    ply = changed / "scenes" / "demo_apartment_0" / "gaussians.ply"
    g = read_ply(ply)
    write_ply(ply, dataclasses.replace(g, opacity_logits=g.opacity_logits - 0.5))
    return changed


@pytest.mark.parametrize("change", ["gaussians", "size"])
def test_a_resume_over_changed_gaussians_or_at_another_size_is_refused(change, exported, run, tmp_path, run_cli):
    """An export interrupted after its first shard, resumed over a run whose Gaussians changed since, or at
    another image size, would finish with shards of two kinds: it is refused, one line, and OUT is left as it was."""
    out = tmp_path / "e"
    shutil.copytree(exported, out)
    (out / "index.json").unlink()
    for shard in json.loads((exported / "index.json").read_text())["shards"][1:]:
        (out / shard["file"]).unlink()
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file() and p.name != ".sagebench.lock"}
    source, size = (_retrained(run, tmp_path), SMALL) if change == "gaussians" else (run, ("--width", "40", *SMALL[2:]))
    code, _, err = run_cli("-q", "export-training", source, "--out", out, "--depth", "--renderer", "cpu", *size)
    assert (code, err.strip()) == (2, f"error: --out: {out} holds an export of other settings or inputs; use a new "
                                      "--out or remove it")
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file() and p.name != ".sagebench.lock"} == before


def test_a_second_export_into_a_locked_out_dir_is_refused(exported, run, tmp_path, run_cli):
    from sagebench.run_lock import run_lock

    shutil.copytree(exported, tmp_path / "e")
    before = {p: p.read_bytes() for p in (tmp_path / "e").rglob("*") if p.is_file() and p.name != ".sagebench.lock"}
    with run_lock(tmp_path / "e"):
        code, _, err = run_cli("export-training", run, "--out", tmp_path / "e", "--depth", "--renderer", "cpu", *SMALL)
    assert code == 2 and "is writing this run directory" in err and len(err.strip().splitlines()) == 1
    assert {p: p.read_bytes() for p in before} == before


# NaVILA's evaluator (evaluation/vlnce_baselines/navila_trainer.py), its parsing written here: the action by the first
# of these patterns found, then the amount
NAVILA_ACTIONS = {"STOP": re.compile(r"\bstop\b", re.I), "MOVE_FORWARD": re.compile(r"\bis move forward\b", re.I),
                  "TURN_LEFT": re.compile(r"\bis turn left\b", re.I),
                  "TURN_RIGHT": re.compile(r"\bis turn right\b", re.I)}
NAVILA_AMOUNTS = {"MOVE_FORWARD": r"move forward (\d+) cm", "TURN_LEFT": r"turn left (\d+) degree",
                  "TURN_RIGHT": r"turn right (\d+) degree"}


def navila_parse(answer: str) -> tuple[str, int | None]:
    """(the action, its amount: cm or degrees) as NaVILA's evaluator reads `answer`; its `match.group` raises on an
    answer without the amount, as there."""
    action = next(name for name, pattern in NAVILA_ACTIONS.items() if pattern.search(answer))
    return action, None if action == "STOP" else int(re.search(NAVILA_AMOUNTS[action], answer).group(1))


def test_navila_layout_is_what_navilas_trainer_reads_and_its_parser_parses(exported, run, tmp_path, run_cli):
    """--navila adds NaVILA's layout from the finished shards (so it also works on a finished export): one PNG per
    view; per split one annotation file (NaVILA's data_path) whose every answer NaVILA's evaluator parses to the
    step's action and amount (25 cm, 15 degrees), with the frames from the start to that step under image_path."""
    shutil.copytree(exported, tmp_path / "e")
    code, _, err = run_cli("-q", "export-training", run, "--out", tmp_path / "e", "--depth", "--renderer", "cpu",
                           "--navila", *SMALL)
    assert code == 0, err
    nav = tmp_path / "e" / "navila"
    info = json.loads((nav / "dataset_info.json").read_text())
    splits = {sh["split"] for sh in json.loads((tmp_path / "e" / "index.json").read_text())["shards"]}
    assert sorted(p.name for p in nav.glob("annotations*")) == sorted(f"annotations_{s}.json" for s in splits)
    rows = [r for s in splits for r in json.loads((nav / info["splits"][s]["data_path"]).read_text())]
    samples = _samples(exported)
    assert info["total_samples"] == len(rows) == len(samples)
    amount = {"STOP": None, "MOVE_FORWARD": 25, "TURN_LEFT": 15, "TURN_RIGHT": 15}
    by_video = {r["video_id"]: r for r in rows}
    for s in samples:
        row = by_video[f"{s['scene_id']}_{s['episode_id']}-{s['step']}"]
        assert row["q"] == s["instruction"] and navila_parse(row["a"]) == (s["action_name"], amount[s["action_name"]])
        assert len(row["frames"]) == s["step"] + 1
        assert (nav / info["splits"][s["split"]]["image_path"] / row["frames"][-1]).read_bytes() == s["rgb"]
    assert {navila_parse(r["a"])[0] for r in rows} >= {"STOP", "MOVE_FORWARD"}


def test_a_step_navilas_evaluator_would_not_execute_is_refused_before_any_shard(run, tmp_path):
    from sagebench.errors import ConfigError
    from sagebench.settings.export_training import TrainingExportConfig
    from sagebench.settings.shared import ActionConfig
    from sagebench.training.export import export_training

    config = TrainingExportConfig(navila=True, actions=ActionConfig(forward_step=0.35, turn_deg=30.0))
    with pytest.raises(ConfigError) as err:
        export_training(run, tmp_path / "e", config)
    assert str(err.value) == ("--navila: NaVILA's evaluator executes moves of 25, 50, 75 cm and turns of 15, 30, 45 "
                              "degrees; this export's are 0.35 m and 30 degrees")
    assert not (tmp_path / "e").exists()