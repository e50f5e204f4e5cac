"""`sagebench run` / `verify`: identical manifests whatever the executor, resume after kill -9, skipping, failures."""

from __future__ import annotations

import copy
import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from sagebench.fileio import is_temporary
from sagebench.pipeline.manifest import hash_run
from sagebench.scene.synth import write_synth_scene
from sagebench.versions import output_versions
from signals import as_from_a_terminal
from test_fuzz_inputs import SPEC, write_scene
from tests.test_collider_convex import u_prism

CONFIG = """scenes = ["scenes/*"]
out = "{out}"
seed = 0
cache_dir = "cache-{out}"
[gen_trajectories]
per_scene = 8
min_geodesic_m = 1.0
[validate]
frames_per_scene = 1
"""
A, B = SCENES = ("tiny_a", "tiny_b")
_QUARTER_TURN = [math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)]  # about Z


def _add_planter(scene: Path, width: float) -> None:
    """A U-shaped planter in the scene's first room: one concave piece for the run to decompose."""
    spec = json.loads((scene / "scene.json").read_text())
    u_prism(width).export(scene / "meshes" / "planter.obj")
    (x0, y0), (x1, y1) = np.min(spec["rooms"][0]["polygon"], axis=0), np.max(spec["rooms"][0]["polygon"], axis=0)
    spec["objects"].append({"instance_id": max(o["instance_id"] for o in spec["objects"]) + 1, "category": "planter",
                            "mesh": "meshes/planter.obj", "room_id": spec["rooms"][0]["id"],
                            "transform": {"translation": [x0 + 0.3, y0 + 0.3, 0.0]}})
    (scene / "scene.json").write_text(json.dumps(spec))


def _walled_tiny_scene(scene: Path, scene_id: str) -> None:
    """The tiny scene of test_fuzz_inputs.py (one 6 x 4 m room) with a wall on each of its four sides, so that
    validate's spot-check frames look at something to align with."""
    spec = copy.deepcopy(SPEC) | {"scene_id": scene_id}
    side = {"rotation_wxyz": _QUARTER_TURN, "scale": [4.2 / 6, 1.0, 1.0]}  # the 6 m wall turned and cut to 4.2 m
    for transform in ({"translation": [3.0, -0.05, 1.25]}, {"translation": [-0.05, 2.0, 1.25]} | side,
                      {"translation": [6.05, 2.0, 1.25]} | side):
        spec["objects"].append({"instance_id": len(spec["objects"]) + 1, "category": "wall", "kind": "wall",
                                "mesh": "meshes/wall.obj", "transform": transform})
    write_scene(scene, spec)


@pytest.fixture(scope="module")
def workspace(tmp_path_factory) -> Path:
    """Two walled tiny rooms, each with a planter of its own width (two concave pieces in the run)."""
    root = tmp_path_factory.mktemp("runs")
    for (name, width), sid in zip((("a", 0.6), ("b", 0.7)), SCENES):
        _walled_tiny_scene(root / "scenes" / name, sid)
        _add_planter(root / "scenes" / name, width)
    return root


def _config(root: Path, out: str, extra: str = "") -> Path:
    path = root / f"{out}.toml"
    path.write_text(CONFIG.format(out=out) + extra)
    return path


@pytest.fixture(scope="module")
def serial_run(workspace) -> Path:
    from sagebench.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["-q", "run", str(_config(workspace, "serial"))])
    assert exc.value.code in (0, None)
    return workspace / "serial"


def _manifest(run: Path) -> bytes:
    return (run / "manifest.json").read_bytes()


def test_manifest_lists_every_output(serial_run):
    manifest = json.loads(_manifest(serial_run))
    files = manifest["files"]
    for sid in SCENES:
        for rel in ("scenes/{}/topdown.npz", "scenes/{}/gaussians.ply", "scenes/{}/scene.usda",
                    "scenes/{}/scene.xml", "scenes/{}/geometry.usdc", "reports/{}/report.json"):
            assert rel.format(sid) in files
        assert any(f.startswith(f"episodes/{sid}/part-") and f.endswith("-00000.parquet") for f in files)
    assert set(manifest["inputs"]) == set(SCENES)
    assert manifest["versions"] == output_versions() and manifest["versions"]["numpy"] == np.__version__
    assert "workers" not in manifest["config"] and manifest["config"]["gen_trajectories"]["per_scene"] == 8
    assert not any(p.startswith(".") for p in files)
    assert manifest["failed"] == {}


@pytest.fixture
def dispatched(monkeypatch) -> list[tuple[str, object, object]]:
    """Every task the run's executor is given: (function name, argument, its result), in submission order."""
    from sagebench.pipeline import run as run_mod

    seen: list[list] = []
    make = run_mod.make_executor

    def spying(*args):
        executor = make(*args)
        submit, wait_any = executor.submit, executor.wait_any

        def spy_submit(fn, arg, **kw):
            handle = submit(fn, arg, **kw)
            seen.append([fn.__name__, arg, handle, None])
            return handle

        def spy_wait(pending):
            got = wait_any(pending)
            for handle, result in got:
                for row in seen:
                    if row[2] is handle:
                        row[3] = result
            return got

        executor.submit, executor.wait_any = spy_submit, spy_wait
        return executor

    monkeypatch.setattr(run_mod, "make_executor", spying)
    return seen


def _pieces(seen) -> list:
    """The piece tasks the run dispatched: (task, outcome) each."""
    return [(arg, result) for name, arg, _, result in seen if name == "run_piece"]


def test_serial_run_decomposes_each_piece_as_a_task(serial_run):
    pieces = [o["concave_pieces"] for sid in SCENES for o in json.loads(
        (serial_run / "scenes" / sid / "colliders" / "colliders.json").read_text())["objects"] if o["concave_pieces"]]
    assert len(pieces) == 2 and all(len(p) == 1 for p in pieces)  # one planter, one piece each


@pytest.mark.parametrize("executor", ["local", "ray"])
def test_pieces_are_spread_over_the_executor_with_the_same_outputs(workspace, serial_run, run_cli, dispatched,
                                                                   executor):
    """Two local workers or Ray: the manifest of the serial run, byte for byte, with each scene's concave piece
    dispatched as a task of its own (one piece each, run in a worker process) before the scene's export."""
    if executor == "ray":
        pytest.importorskip("ray")
    name = "pool" if executor == "local" else "ray"
    code, out, err = run_cli("-q", "run", _config(workspace, name), "--executor", executor, "--workers", "2")
    assert code == 0, out + err
    assert _manifest(workspace / name) == _manifest(serial_run)
    pieces = _pieces(dispatched)
    assert sorted(t.scene_id for t, _ in pieces) == list(SCENES)
    assert len({t.key for t, _ in pieces}) == 2 and all(o.method and not o.error for _, o in pieces)
    assert all(int(o.worker.rsplit(":", 1)[1]) != os.getpid() for _, o in pieces)
    names = [n for n, *_ in dispatched]
    assert names.count("plan_export") == 2 and names.count("run_task") == 8
    at = {(n, arg.scene_id, getattr(arg, "stage", "")): i for i, (n, arg, *_) in enumerate(dispatched)}
    for sid in SCENES:  # the export finds its piece done
        assert at[("run_piece", sid, "")] < at[("run_task", sid, "export_usd")]
    assert re.search(r"collider pieces\s+ran\s+2\b", out), out
    index = {p["cache_key"] for sid in SCENES for o in json.loads(
        (workspace / name / "scenes" / sid / "colliders" / "colliders.json").read_text())["objects"]
             for p in o["concave_pieces"]}
    assert index == {t.key for t, _ in pieces}


@pytest.mark.slow
def test_two_demo_apartments_run_alike_serially_and_on_two_workers(tmp_path, run_cli):
    """The tests above at full scale: two demo apartments (five rooms, doors, 20 trajectories each, a planter each)
    run serially and on two local workers give the same manifest, byte for byte, listing every output."""
    for name, seed, width in (("a", 0, 0.6), ("b", 1, 0.7)):
        write_synth_scene(tmp_path / "scenes" / name, seed=seed)
        _add_planter(tmp_path / "scenes" / name, width)
    for name, args in (("serial", ()), ("pool", ("--executor", "local", "--workers", "2"))):
        config = _config(tmp_path, name)
        config.write_text(config.read_text().replace("per_scene = 8\nmin_geodesic_m = 1.0\n", "per_scene = 20\n"))
        code, out, err = run_cli("-q", "run", config, *args)
        assert code == 0, out + err
        assert re.search(r"collider pieces\s+ran\s+2\b", out), out
    manifest = json.loads(_manifest(tmp_path / "serial"))
    assert _manifest(tmp_path / "pool") == _manifest(tmp_path / "serial")
    sids = ("demo_apartment_0", "demo_apartment_1")
    assert set(manifest["inputs"]) == set(sids) and manifest["failed"] == {}
    assert manifest["config"]["gen_trajectories"]["per_scene"] == 20
    for sid in sids:
        for rel in ("scenes/{}/topdown.npz", "scenes/{}/gaussians.ply", "scenes/{}/scene.usda",
                    "scenes/{}/scene.xml", "scenes/{}/geometry.usdc", "reports/{}/report.json"):
            assert rel.format(sid) in manifest["files"]


def test_quality_spreads_both_its_passes_over_the_executor(workspace, run_cli, dispatched):
    """quality also decomposes each piece as balanced does (and keeps the closer): both passes' pieces run as
    tasks of their own before the export, which then finds every piece it looks up in the cache."""
    from sagebench.collider_export.coacd_cache import PartCache
    from sagebench.collider_export.decompose import mode_passes
    from sagebench.collider_export.pieces import piece_key
    from sagebench.settings.export_usd import ColliderSettings, ExportConfig
    from sagebench.stages.export_usd import scene_pieces

    extra = '[export_usd]\ncolliders = { mode = "quality" }\n'
    code, out, err = run_cli("-q", "run", _config(workspace, "quality", extra), "--workers", "2")
    assert code == 0, out + err
    pieces = _pieces(dispatched)
    assert sorted(ColliderSettings.model_validate(t.colliders).mode for t, _ in pieces) == ["balanced"] * 2 + [
        "quality"] * 2
    assert all(o.method and not o.error for _, o in pieces)
    run, cache = workspace / "quality", PartCache(workspace / "cache-quality")
    config = ExportConfig.model_validate({"colliders": {"mode": "quality"}})
    assert len(mode_passes(config.colliders)) == 2
    for sid in SCENES:
        jobs, band = scene_pieces(run, sid, config, cache)
        assert {piece_key(p, c, band) for p, c in jobs} <= {t.key for t, _ in pieces}  # nothing left to the export


def _stage_counts(out: str) -> dict[str, tuple[int, int, int]]:
    """The summary's per-stage lines: name -> (ran, skipped, failed)."""
    found = re.findall(r"^\s+(\w+)\s+ran\s+(\d+)\s+skipped\s+(\d+)\s+failed\s+(\d+)", out, re.MULTILINE)
    return {name: tuple(map(int, counts)) for name, *counts in found}


def test_rerun_skips_every_stage(workspace, serial_run, run_cli):
    before, files = _manifest(serial_run), hash_run(serial_run)
    code, out, _ = run_cli("-q", "run", _config(workspace, "serial"))
    assert code == 0
    assert _stage_counts(out) == dict.fromkeys(("build_scene", "gen_trajectories", "export_usd", "validate"),
                                               (0, 2, 0)), out
    assert _manifest(serial_run) == before and hash_run(serial_run) == files


def _plant_user_dotfiles(*dirs: Path) -> list[Path]:
    """A user's own hidden files that look like temporaries to a careless cleaner; each must survive a run."""
    planted = []
    for d in dirs:
        for name, is_dir in ((".x.old", False), (".y.tmp", False), (".cache.tmp", True), (".prev.old", True)):
            p = d / name
            p.mkdir(parents=True) if is_dir else (d.mkdir(parents=True, exist_ok=True), p.write_text("mine"))
            planted.append(p)
    return planted


def test_killed_run_resumes_to_the_same_manifest(workspace, serial_run, run_cli):
    config = _config(workspace, "killed")
    scene_copy = workspace / "killed_scenes" / "scenes"  # the inputs, with the user's dotfiles planted in one
    shutil.copytree(workspace / "scenes", scene_copy)
    config.write_text(config.read_text().replace('"scenes/*"', '"killed_scenes/scenes/*"'))
    kept = _plant_user_dotfiles(workspace / "killed", workspace / "killed" / "scenes", scene_copy / "a",
                                scene_copy / "a" / "meshes")
    proc = subprocess.Popen([sys.executable, "-m", "sagebench", "-q", "run", str(config)], cwd=workspace,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    stamps = workspace / "killed" / ".stamps"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None and len(list(stamps.rglob("*.json"))) < 3:
        time.sleep(0.05)
    assert proc.poll() is None, "the run ended before it could be killed midway"
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert not (workspace / "killed" / "manifest.json").exists()
    stamped = len(list(stamps.rglob("*.json")))
    code, out, _ = run_cli("-q", "run", config)
    assert code == 0
    counts = _stage_counts(out)
    assert len(counts) == 4 and all(ran + skipped == 2 and failed == 0 for ran, skipped, failed in counts.values())
    assert sum(skipped for _, skipped, _ in counts.values()) == stamped >= 3  # finished stages are not redone
    resumed, serial = json.loads(_manifest(workspace / "killed")), json.loads(_manifest(serial_run))
    assert (resumed["files"], resumed["inputs"]) == (serial["files"], serial["inputs"])  # scenes copied elsewhere
    assert not [p for p in (workspace / "killed").rglob(".*") if is_temporary(p.name)]
    assert all(p.exists() for p in kept), [p for p in kept if not p.exists()]


def test_a_resumed_run_removes_only_its_own_leftovers(workspace, serial_run, run_cli):
    run = workspace / "leftovers"
    shutil.copytree(serial_run, run)
    config = _config(workspace, "leftovers")
    kept = _plant_user_dotfiles(run, run / "scenes" / A, run / "episodes", workspace / "scenes" / "b")
    ours = [run / "scenes" / A / ".topdown.npz.sagebench-abcd1234.tmp",
            run / "episodes" / f".{B}.sagebench-abcd1234.old" / "part-00000.parquet",
            run / ".manifest.json.sagebench-0000aaaa.tmp"]
    for p in ours:
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_bytes(b"half")
    theirs = workspace / "scenes" / "b" / ".scene.json.sagebench-abcd1234.tmp"  # in an input scene: not ours
    theirs.write_text("a user's file, whatever its name")
    try:
        code, out, err = run_cli("-q", "run", config)
        assert code == 0, out + err
        assert all(p.exists() for p in kept) and theirs.exists()
        assert not any(p.exists() for p in ours) and not ours[1].parent.exists()
        assert _manifest(run) == _manifest(serial_run)
    finally:
        for p in [*kept, theirs]:
            shutil.rmtree(p) if p.is_dir() else p.unlink()


def _hold_lock(run: Path) -> subprocess.Popen:
    """Another process holding RUN's lock, as a running `sagebench run` would, until it is killed."""
    proc = subprocess.Popen([sys.executable, "-c", "import sys, time\nfrom pathlib import Path\n"
                             "from sagebench.run_lock import run_lock\nwith run_lock(Path(sys.argv[1])):\n"
                             "    print('locked', flush=True)\n    time.sleep(600)\n", str(run)],
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline() == "locked\n"
    return proc


def test_a_second_run_on_a_locked_directory_is_refused(workspace, run_cli):
    run = workspace / "locked"
    run.mkdir()
    holder = _hold_lock(run)
    try:
        before = sorted(p.name for p in run.iterdir())
        code, out, err = run_cli("-q", "run", _config(workspace, "locked"))
        assert code == 2 and out == ""
        assert err.splitlines() == [f"error: {run}: another sagebench command (pid {holder.pid}) is writing this run "
                                    "directory; wait for it to end or choose another"]
        assert sorted(p.name for p in run.iterdir()) == before == [".sagebench.lock"]
    finally:
        holder.kill()
        holder.wait()
    # the holder died without releasing anything: the kernel dropped its lock, and a run may take it
    from sagebench.run_lock import run_lock

    with run_lock(run) as path:
        assert path == run / ".sagebench.lock" and path.read_text() == f"{os.getpid()}\n"


def _files(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_a_refused_run_leaves_the_live_runs_files_alone(workspace, run_cli):
    """The live run's half-written files (temporaries by name) are its own while it holds the lock: a second
    run that is refused must not clean them up, nor touch anything else."""
    run = workspace / "live"
    (run / "scenes" / A).mkdir(parents=True)
    (run / "manifest.json").write_text("{}\n")  # a previous run's
    (run / ".stamps" / A).mkdir(parents=True)
    (run / ".stamps" / A / "build_scene.json").write_text("{}\n")
    live = [run / "scenes" / A / ".topdown.npz.sagebench-abcd1234.tmp",
            run / ".manifest.json.sagebench-0000aaaa.tmp",
            run / ".stamps" / A / ".build_scene.json.sagebench-0000bbbb.tmp"]
    for p in live:
        p.write_bytes(b"being written")
    assert all(is_temporary(p.name) for p in live)
    holder = _hold_lock(run)
    try:
        before = _files(run)
        code, out, err = run_cli("-q", "run", _config(workspace, "live"))
        assert code == 2 and out == "" and f"(pid {holder.pid})" in err
        assert _files(run) == before
    finally:
        holder.kill()
        holder.wait()


def test_the_refusal_names_the_holders_pid_over_a_longer_stale_one(workspace):
    """The lock file keeps the last holder's pid; a new holder with a shorter pid must not leave its tail."""
    from sagebench.run_lock import RunLockedError, run_lock

    run = workspace / "stale_pid"
    run.mkdir()
    (run / ".sagebench.lock").write_text("4194304999999\n")  # longer than any pid
    holder = _hold_lock(run)
    try:
        with pytest.raises(RunLockedError) as err:
            with run_lock(run):
                pass
        assert str(err.value) == (f"{run}: another sagebench command (pid {holder.pid}) is writing this run "
                                  "directory; wait for it to end or choose another")
        assert (run / ".sagebench.lock").read_text() == f"{holder.pid}\n"
    finally:
        holder.kill()
        holder.wait()


def test_two_real_runs_on_one_directory(workspace):
    config = _config(workspace, "raced")
    first = subprocess.Popen([sys.executable, "-m", "sagebench", "-q", "run", str(config)], cwd=workspace,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lock = workspace / "raced" / ".sagebench.lock"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and first.poll() is None and not (lock.exists() and lock.read_text()):
        time.sleep(0.02)
    second = subprocess.run([sys.executable, "-m", "sagebench", "-q", "run", str(config)], cwd=workspace,
                            capture_output=True, text=True)
    first.kill()
    first.wait()
    assert second.returncode == 2, second.stderr
    assert second.stderr.splitlines() == [
        f"error: {workspace / 'raced'}: another sagebench command (pid {first.pid}) is writing this run directory; wait "
        "for it to end or choose another"]


@pytest.mark.parametrize("out, scenes, field, says", [
    ("scenes/a/run", "scenes/*", "out", "the run directory {out} is inside the input scene {scene}"),
    ("scenes/a", "scenes/*", "out", "the run directory {out} is inside the input scene {scene}"),
    ("nested", "nested/scenes/*", "scenes", "the input scene {scene} is inside {out}'s output folders"),
])
def test_out_and_scenes_may_not_overlap(workspace, run_cli, out, scenes, field, says):
    root = workspace / f"overlap_{field}_{out.count('/')}"
    shutil.copytree(workspace / "scenes" / "a", root / scenes.replace("*", "a"))
    config = root / "run.toml"
    config.write_text(f'scenes = ["{scenes}"]\nout = "{out}"\n')
    before = sorted(p.relative_to(root) for p in root.rglob("*"))
    code, _, err = run_cli("-q", "run", config)
    scene = root / scenes.replace("*", "a")
    assert code == 2
    assert err.splitlines()[0].startswith(f"error: {config}: {field}: " + says.format(out=root / out, scene=scene))
    assert len(err.splitlines()) == 1 and sorted(p.relative_to(root) for p in root.rglob("*")) == before


def test_verify_names_a_flipped_byte(workspace, serial_run, run_cli):
    run = workspace / "flipped"
    shutil.copytree(serial_run, run)
    code, out, _ = run_cli("verify", run)
    assert code == 0 and out.startswith("ok:")
    shard = sorted((run / "episodes" / B).glob("part-*.parquet"))[0]
    data = bytearray(shard.read_bytes())
    data[200] ^= 0x01
    shard.write_bytes(bytes(data))
    code, out, _ = run_cli("verify", run)
    assert code == 1
    assert out.splitlines() == [f"changed: {shard.relative_to(run).as_posix()}"]


def test_verify_regenerate_matches_and_names_other_library_versions(workspace, serial_run, run_cli):
    # the run as if made with another numpy, and one shard's hash as that numpy gave it: a regeneration matches
    # every other file, and names numpy as the likely cause of the one difference
    run = workspace / "older_numpy"
    shutil.copytree(serial_run, run)
    manifest = json.loads(_manifest(run))
    manifest["versions"]["numpy"] = "1.0.0"
    shard = sorted((run / "episodes" / A).glob("part-*.parquet"))[0].relative_to(run).as_posix()
    manifest["files"][shard] = "0" * 64
    (run / "manifest.json").write_text(json.dumps(manifest))
    code, out, err = run_cli("verify", run, "--regenerate", "--config", workspace / "serial.toml")
    assert code == 1, out + err
    assert out.splitlines() == [
        f"changed: {shard}",
        f"likely cause: other library versions than the run was made with: numpy 1.0.0 -> {np.__version__}"]


def test_a_broken_scene_fails_alone(workspace, run_cli):
    root = workspace / "with_broken"
    for name in ("a", "b"):
        shutil.copytree(workspace / "scenes" / name, root / "scenes" / name)
    broken = root / "scenes" / "c"
    shutil.copytree(workspace / "scenes" / "a", broken)
    spec = json.loads((broken / "scene.json").read_text())
    spec["scene_id"] = "broken"
    (broken / "scene.json").write_text(json.dumps(spec))
    mesh = broken / spec["objects"][2]["mesh"]
    mesh.write_bytes(mesh.read_bytes()[:40])
    code, out, _ = run_cli("-q", "run", _config(root, "out"))
    assert code == 1
    assert "run " in out and "3 scenes" in out and "2 scenes complete" in out
    assert f"FAILED broken at build_scene: {broken / 'scene.json'}: objects[2].mesh: cannot read mesh" in out
    files = json.loads((root / "out" / "manifest.json").read_text())["files"]
    assert f"reports/{A}/report.json" in files and not any("broken" in f for f in files)
    failure = f"{broken / 'scene.json'}: objects[2].mesh: cannot read mesh"
    manifest = json.loads((root / "out" / "manifest.json").read_text())
    assert manifest["failed"]["broken"]["stage"] == "build_scene" and list(manifest["failed"]) == ["broken"]
    assert manifest["failed"]["broken"]["message"].startswith(failure)
    code, out, _ = run_cli("verify", root / "out")  # every file matches, but a stage failed: not ok
    assert code == 1 and out.startswith(f"failed: broken at build_scene: {failure}") and "ok:" not in out
    assert len(out.splitlines()) == 1
    # scene b and the broken one leave the config: the manifest drops them, and verify passes on what is left
    config = root / "only_a.toml"
    config.write_text(CONFIG.format(out="out").replace('"scenes/*"', '"scenes/a"'))
    code, out, _ = run_cli("-q", "run", config)
    assert code == 0, out
    manifest = json.loads((root / "out" / "manifest.json").read_text())
    assert manifest["failed"] == {} and list(manifest["inputs"]) == [A]
    assert {f.split("/")[1] for f in manifest["files"]} == {A}
    assert (root / "out" / "episodes" / B).is_dir()  # still there: sagebench removes no outputs
    code, out, _ = run_cli("verify", root / "out")
    assert code == 0 and out.startswith("ok:"), out


def test_bad_config_is_one_line(workspace, run_cli):
    bad = workspace / "bad.toml"
    bad.write_text('scenes = ["scenes/*"]\nout = "x"\nworkers = 0\n')
    code, _, err = run_cli("run", bad)
    assert code == 2 and f"{bad}: workers: Input should be greater than or equal to 1" in err
    bad.write_text('scenes = ["nowhere/*"]\nout = "x"\n')
    code, _, err = run_cli("run", bad)
    assert code == 2 and "scenes[0]: 'nowhere/*' matches no scene directory" in err
    bad.write_text('scenes = [\n')
    code, _, err = run_cli("run", bad)
    assert code == 2 and "malformed TOML" in err
    assert not (workspace / "x").exists()


def test_ctrl_c_on_a_two_worker_run_is_one_line_and_exit_130(workspace):
    """Ctrl-C reaches every process of the terminal's group: the workers (and the fork servers they start for
    collider pieces) end without tracebacks of their own, and the run says once that it was interrupted."""
    config = _config(workspace, "ctrl_c")
    proc = subprocess.Popen([sys.executable, "-m", "sagebench", "run", str(config), "--workers", "2"], cwd=workspace,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True,
                            preexec_fn=as_from_a_terminal)
    stamps = workspace / "ctrl_c" / ".stamps"
    try:
        deadline = time.monotonic() + 180
        while time.monotonic() < deadline and proc.poll() is None and len(list(stamps.rglob("*.json"))) < 3:
            time.sleep(0.05)
        assert proc.poll() is None, "the run ended before it could be interrupted"
        os.killpg(proc.pid, signal.SIGINT)  # as a terminal sends Ctrl-C: to the whole foreground group
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
    text = err.decode()
    assert proc.returncode == 130 and "Traceback" not in text, text
    assert text.strip().splitlines()[-1] == "error: interrupted: finished stages are kept; run again to go on from them"
