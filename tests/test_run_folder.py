"""The run folder's claim (run_folder.py, run_lock.py) under attack: a lock that is a link, a hard link, a FIFO,
a directory or another user's file; a user's folder; a second writer; unwritable places. Every writer is
refused in one line (exit 2) and the whole tree is hashed before and after: nothing of the user's changes.

Permission cases run with the capabilities that let root ignore file modes dropped (setpriv), since CI runs
as root. Counted with the other attacks in test_fuzz_safety.py.
"""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest
from test_fuzz_inputs import snapshot
from test_fuzz_safety import TOML, _toml, copy_made, refused

def _writers(scene: Path, out: Path, config: Path) -> dict[str, list]:
    """Every command that writes into a run directory, aimed at `out`."""
    return {
        "run": ["run", config],
        "run-force": ["run", config, "--force"],
        "build-scene": ["build-scene", scene, "--out", out],
        "build-scene-force": ["build-scene", scene, "--out", out, "--force"],
        "gen-trajectories": ["gen-trajectories", out, "--per-scene", "2"],
        "gen-trajectories-force": ["gen-trajectories", out, "--per-scene", "2", "--force"],
        "export-usd": ["export-usd", out, "--colliders", "fast"],
        "export-usd-force": ["export-usd", out, "--colliders", "fast", "--force"],
        "validate": ["validate", out, "--frames-per-scene", "0"],
        "validate-force": ["validate", out, "--frames-per-scene", "0", "--force"],
        "demo": ["demo", "--out", out],
        "demo-force": ["demo", "--out", out, "--force"],
        # the claim comes first: any existing FILE will do (the config), it is read only once the run is claimed
        "import-sage-episodes": ["import-sage-episodes", config, "--run", out, "--scene", "tiny"],
        "import-sage-episodes-force": ["import-sage-episodes", config, "--run", out, "--scene", "tiny", "--force"],
    }


WRITERS = list(_writers(Path(), Path(), Path()))


# ---------------------------------------------------------------- the lock never follows a link


def _link_lock(out: Path, target: Path) -> None:
    (out / ".sagebench.lock").symlink_to(target)


def _hard_lock(out: Path, target: Path) -> None:
    os.link(target, out / ".sagebench.lock")


def _fifo_lock(out: Path, target: Path) -> None:
    os.mkfifo(out / ".sagebench.lock")


def _dir_lock(out: Path, target: Path) -> None:
    (out / ".sagebench.lock").mkdir()


def _foreign_lock(out: Path, target: Path) -> None:
    (out / ".sagebench.lock").write_text("")
    os.chown(out / ".sagebench.lock", 65534, 65534)


LOCKS = {"symlink": (_link_lock, "(a link)"), "hard-link": (_hard_lock, "(hard-linked elsewhere (2 links))"),
         "fifo": (_fifo_lock, "(not a regular file)"), "directory": (_dir_lock, "(not a regular file)"),
         "other-user": (_foreign_lock, "(owned by uid 65534, not by you")}


@pytest.mark.parametrize("writer", WRITERS)
@pytest.mark.parametrize("lock", list(LOCKS))
def test_a_lock_that_is_not_sagebench_s_is_refused_and_its_target_kept(lock, writer, tiny_run, tiny_scene, run_cli,
                                                                       tmp_path):
    if lock == "other-user" and os.geteuid() != 0:
        pytest.skip("chown to another user needs root")
    out = tmp_path / "run"
    shutil.copytree(tiny_run, out, symlinks=True)
    target = tmp_path / "precious.txt"
    target.write_text("the user's file, whatever a lock does\n")
    plant, says = LOCKS[lock]
    plant(out, target)
    args = _writers(tiny_scene, out, _toml(tmp_path / "run.toml", tiny_scene, out))[writer]
    line = refused(run_cli, args, tmp_path, f".sagebench.lock: not sagebench's lock file {says}")
    assert "nothing was written" in line
    assert target.read_text() == "the user's file, whatever a lock does\n"


# ---------------------------------------------------------------- a user's folder is never written over


def _users_folder(out: Path) -> None:
    """The issue's folder: a README, a manifest and a file in a scenes/<id>/ of the user's."""
    (out / "scenes" / "demo_apartment_0").mkdir(parents=True)
    (out / "README.md").write_text("# my notes\n")
    (out / "manifest.json").write_text('{"mine": true}\n')
    (out / "scenes" / "demo_apartment_0" / "important.txt").write_text("do not delete\n")
    (out / "notes.txt").write_text("mine\n")


@pytest.mark.parametrize("writer", WRITERS)
def test_a_users_folder_comes_out_byte_identical(writer, tiny_scene, run_cli, tmp_path):
    out = tmp_path / "mine"
    _users_folder(out)
    args = _writers(tiny_scene, out, _toml(tmp_path / "run.toml", tiny_scene, out))[writer]
    clashes = writer.split("-force")[0] in ("run", "build-scene", "export-usd", "demo")  # they write scenes/
    expect = ("even with --force it never replaces" if clashes else "") if writer.endswith("-force") else \
        "holds files that are not a sagebench run's (README.md, manifest.json, notes.txt and 1 more)"
    refused(run_cli, args, tmp_path, expect)  # without a clash, the stage's own refusal: no scene to work on


def test_force_writes_the_run_beside_the_users_files_and_never_changes_them(tiny_scene, run_cli, tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("mine\n")
    (out / ".hidden").write_text("mine too\n")
    (out / "data").mkdir()
    (out / "data" / "x.csv").write_text("1,2\n")
    before = snapshot(out)
    config = _toml(tmp_path / "run.toml", tiny_scene, out)
    refused(run_cli, ["run", config], tmp_path, "holds files that are not a sagebench run's (data/, notes.txt)")
    code, _, err = run_cli("-q", "run", config, "--force")
    assert code == 0, err
    after = snapshot(out)
    assert {k: after[k] for k in before} == before
    assert (out / "manifest.json").is_file() and (out / "scenes" / "tiny" / "topdown.npz").is_file()
    code, _, err = run_cli("-q", "run", config, "--force")  # again: every stage skipped, the user's files kept
    assert code == 0, err
    assert {k: snapshot(out)[k] for k in before} == before


def test_an_artist_scene_under_out_scenes_is_not_a_run(tiny_scene, run_cli, tmp_path):
    """scenes/<id>/ with files no stage writes (a user's scene with its notes) is the user's, even with --force."""
    out = tmp_path / "project"
    shutil.copytree(tiny_scene, out / "scenes" / "tiny")
    (out / "scenes" / "tiny" / "notes.md").write_text("mine\n")
    refused(run_cli, ["build-scene", tiny_scene, "--out", out, "--force"], tmp_path,
            "scenes/tiny/notes.md is not a sagebench run's and lies where `build-scene` writes")


def test_an_input_scene_inside_the_output_folders_is_refused(tiny_scene, run_cli, tmp_path):
    out = tmp_path / "run"
    scene = out / "scenes" / "tiny"
    shutil.copytree(tiny_scene, scene)
    refused(run_cli, ["build-scene", scene, "--out", out], tmp_path,
            f"SCENE_DIR: the input scene {scene} is inside {out}'s output folders")


def test_the_users_hidden_files_survive_a_rebuild(tiny_run, tiny_scene, run_cli, tmp_path):
    out = tmp_path / "run"
    shutil.copytree(tiny_run, out)
    mine = [out / "scenes" / "tiny" / ".my-notes", out / "episodes" / "tiny" / ".keep"]
    for p in mine:
        p.write_text("mine\n")
    assert run_cli("build-scene", tiny_scene, "--out", out, "--object-density", "20")[0] == 0
    assert run_cli("gen-trajectories", out, "--per-scene", "2", "--min-geodesic", "1")[0] == 0
    assert all(p.read_text() == "mine\n" for p in mine)


@pytest.mark.parametrize("make, expect", [
    (lambda p: p.write_text("x"), "is a file, not a run directory"),
    (lambda p: p.symlink_to(p.parent / "nowhere"), "is a file, not a run directory"),
])
def test_an_out_that_is_a_file_is_one_line(make, expect, tiny_scene, run_cli, tmp_path):
    out = tmp_path / "out"
    make(out)
    refused(run_cli, ["run", _toml(tmp_path / "run.toml", tiny_scene, out)], tmp_path, f"{out}: {expect}")
    refused(run_cli, ["build-scene", tiny_scene, "--out", out], tmp_path, f"{out}: {expect}")


# ---------------------------------------------------------------- exports go to a folder of their own


def _exporter(name: str, run: Path, out: Path) -> list:
    return {"export-vlnce": ["export-vlnce", run, "--out", out], "export-sage": ["export-sage", run, "--out", out],
            "export-habitat": ["export-habitat", run, "--out", out],
            "export-training": ["export-training", run, "--out", out, "--renderer", "cpu", "--width", "16",
                                "--height", "16"]}[name]


EXPORTERS = ["export-vlnce", "export-habitat", "export-training", "export-sage"]
EXPORT_OUTS = {  # where OUT is (the run copied to tmp_path/run) -> what the one line says
    "the-run": (lambda tmp: tmp / "run", "lies inside the run"),
    "inside-the-run": (lambda tmp: tmp / "run" / "exports" / "x", "lies inside the run"),
    "a-link-into-the-run": (lambda tmp: (tmp / "link").symlink_to(tmp / "run" / "scenes") or tmp / "link" / "x",
                            "lies inside the run"),
    "a-users-folder": (lambda tmp: _users_folder(tmp / "mine") or tmp / "mine",
                       "is not empty and holds no {exporter} output; use a new --out"),
    "locked": (lambda tmp: (tmp / "exp").mkdir() or tmp / "exp",
               "is writing this run directory; wait for it to end or choose another"),
}


@pytest.mark.parametrize("where", list(EXPORT_OUTS))
@pytest.mark.parametrize("exporter", EXPORTERS)
def test_an_export_never_writes_into_the_run_a_users_folder_or_a_locked_one(exporter, where, tiny_run, run_cli,
                                                                            tmp_path):
    """export-vlnce wrote vocab.txt, <split>/ and scenes/<id>/<id>.glb over whatever OUT held (the run itself
    included, where its lock and manifest do not cover them); now OUT is claimed as a run folder is."""
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    make, expect = EXPORT_OUTS[where]
    out = make(tmp_path)
    holder = _hold_lock(out) if where == "locked" else None
    try:
        refused(run_cli, _exporter(exporter, run, out), tmp_path, expect.format(exporter=exporter))
    finally:
        if holder is not None:
            holder.kill()
            holder.wait()


def test_an_export_vlnce_goes_again_into_its_own_output(tiny_run, run_cli, tmp_path):
    out = tmp_path / "vlnce"
    assert run_cli("export-vlnce", tiny_run, "--out", out)[0] == 0
    first = snapshot(out)
    code, _, err = run_cli("export-vlnce", tiny_run, "--out", out)
    assert code == 0, err
    assert snapshot(out) == first


# ---------------------------------------------------------------- one writer at a time, whatever the command


def _hold_lock(run: Path) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-c", "import sys, time\nfrom pathlib import Path\n"
                             "from sagebench.run_lock import run_lock\nwith run_lock(Path(sys.argv[1])):\n"
                             "    print('locked', flush=True)\n    time.sleep(600)\n", str(run)],
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline() == "locked\n"
    return proc


def test_every_writer_is_refused_while_another_holds_the_run(tiny_run, tiny_scene, run_cli, tmp_path):
    out = tmp_path / "run"
    shutil.copytree(tiny_run, out)
    holder = _hold_lock(out)
    try:
        for name, args in _writers(tiny_scene, out, _toml(tmp_path / "run.toml", tiny_scene, out)).items():
            line = refused(run_cli, args, tmp_path, f"another sagebench command (pid {holder.pid}) is writing this "
                                                    "run directory; wait for it to end or choose another")
            assert line.startswith(f"error: {out}: "), (name, line)
    finally:
        holder.kill()
        holder.wait()


def test_a_failed_command_leaves_no_lock_and_no_folder_it_made(tiny_scene, run_cli, tmp_path):
    scene = tmp_path / "scene"
    shutil.copytree(tiny_scene, scene)
    (scene / "scene.json").write_text("{")
    refused(run_cli, ["build-scene", scene, "--out", tmp_path / "a" / "b" / "run"], tmp_path, "malformed JSON")
    assert not (tmp_path / "a").exists()


def test_a_claim_nests_in_one_process_and_the_lock_excludes_every_other_holder(tmp_path):
    """demo claims its folder and starts a run that claims it again; the lock itself is never re-entrant (a second
    holder in the same process, as export-training's, is refused too)."""
    from sagebench.run_folder import claim_run_dir
    from sagebench.run_lock import RunLockedError, run_lock

    with claim_run_dir(tmp_path, "demo"), claim_run_dir(tmp_path, "run"):
        assert (tmp_path / ".sagebench.lock").read_text() == f"{os.getpid()}\n"
        with pytest.raises(RunLockedError), run_lock(tmp_path):
            pass
        proc = subprocess.run([sys.executable, "-c", "import sys\nfrom pathlib import Path\n"
                               "from sagebench.run_lock import run_lock\nwith run_lock(Path(sys.argv[1])): pass\n",
                               str(tmp_path)], capture_output=True, text=True)
        assert proc.returncode == 1 and "RunLockedError" in proc.stderr
    with run_lock(tmp_path):
        pass
    with pytest.raises(RuntimeError), run_lock(tmp_path):
        raise RuntimeError("the lock file this call found stays")
    assert (tmp_path / ".sagebench.lock").is_file()


# ---------------------------------------------------------------- permissions, with root's overrides dropped


def _as_user(args: list, **kw) -> subprocess.CompletedProcess:
    """Run `sagebench ARGS` in a process that file modes bind: as root, without CAP_DAC_OVERRIDE and
    CAP_DAC_READ_SEARCH (setpriv), as CI runs the suite as root; as is, otherwise."""
    cmd = [sys.executable, "-m", "sagebench", *map(str, args)]
    if os.geteuid() == 0:
        cmd = ["setpriv", "--bounding-set=-dac_override,-dac_read_search", "--", *cmd]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=300, **kw)


@pytest.fixture(scope="module")
def modes_bind(tmp_path_factory) -> None:
    if os.geteuid() != 0:
        return
    probe = tmp_path_factory.mktemp("probe") / "f"
    probe.write_text("x")
    probe.chmod(0)
    if shutil.which("setpriv") is None:
        pytest.skip("running as root without setpriv: file modes cannot be made to bind")
    ran = subprocess.run(["setpriv", "--bounding-set=-dac_override,-dac_read_search", "--", "cat", str(probe)],
                         capture_output=True)
    if ran.returncode == 0 or b"Permission denied" not in ran.stderr:
        pytest.skip(f"setpriv could not drop root's file-mode overrides here ({ran.stderr.decode().strip()})")


def _one_line(proc: subprocess.CompletedProcess, expect: str) -> None:
    lines = proc.stderr.splitlines()
    assert (proc.returncode, proc.stdout, len(lines)) == (2, "", 1), proc.stderr
    assert expect in lines[0] and "Traceback" not in proc.stderr, lines[0]


def test_a_read_only_parent_of_out_is_one_line(modes_bind, tiny_scene, tmp_path):
    parent = tmp_path / "ro"
    parent.mkdir()
    parent.chmod(0o555)
    config = _toml(tmp_path / "run.toml", tiny_scene, parent / "run")
    try:
        before = snapshot(tmp_path)
        _one_line(_as_user(["build-scene", tiny_scene, "--out", parent / "run"]), f"{parent / 'run'}: cannot create: "
                                                                                   "Permission denied")
        _one_line(_as_user(["run", config]), f"{parent / 'run'}: cannot create: Permission denied")
        assert snapshot(tmp_path) == before
    finally:
        parent.chmod(0o755)


def test_a_read_only_out_is_one_line(modes_bind, tiny_run, tmp_path):
    out = tmp_path / "run"
    shutil.copytree(tiny_run, out)
    for d in (out, *[p for p in out.rglob("*") if p.is_dir()]):
        d.chmod(0o555)
    try:
        before = snapshot(tmp_path)
        _one_line(_as_user(["gen-trajectories", out, "--per-scene", "2"]), f"{out}/.sagebench.lock: cannot create the "
                                                                          "run lock: Permission denied")
        assert snapshot(tmp_path) == before
    finally:
        for d in (out, *[p for p in out.rglob("*") if p.is_dir()]):
            d.chmod(0o755)


@pytest.mark.parametrize("what", ["mesh", "meshes-dir", "scene-json"])
def test_an_unreadable_input_is_one_line(what, modes_bind, tiny_scene, tmp_path):
    scene = tmp_path / "scene"
    shutil.copytree(tiny_scene, scene)
    target = {"mesh": scene / "meshes" / "table.glb", "meshes-dir": scene / "meshes",
              "scene-json": scene / "scene.json"}[what]
    target.chmod(0)
    try:
        for command in (["check-scene", scene], ["build-scene", scene, "--out", tmp_path / "run"]):
            proc = _as_user(command)
            _one_line(proc, "Permission denied" if what != "meshes-dir" else "scene.json: objects[0].mesh")
        assert not (tmp_path / "run").exists()
    finally:
        target.chmod(stat.S_IRWXU | stat.S_IRGRP | stat.S_IXGRP | stat.S_IROTH | stat.S_IXOTH)


# ---------------------------------------------------------------- --force never replaces an input


@pytest.fixture(scope="module")
def interiorgs_src(tiny_scene, tmp_path_factory) -> Path:
    """The tiny scene as an InteriorGS folder (tests/interiorgs_fixture.py). Read-only: copy it."""
    from interiorgs_fixture import write_interiorgs_folder

    out = tmp_path_factory.mktemp("igs") / "0001_1"
    write_interiorgs_folder(tiny_scene, out)
    return out


FURNITURE = Path(__file__).parent / "fixtures" / "sh3d_cc0"
SOURCE_CASES = {  # (command's input, where OUT is) -> what the one line says
    "interiorgs-out-is-src": ("src", lambda src: src, "is the input {src} (SRC)"),
    "interiorgs-out-holds-src": ("src", lambda src: src.parent, "holds the input {src} (SRC)"),
    "interiorgs-out-inside-src": ("src", lambda src: src / "scene", "lies inside the input {src} (SRC)"),
    "interiorgs-out-holds-collision-usd": ("usd", lambda usd: usd.parent, "holds the input {src} (--collision-usd)"),
    "synth-out-is-furniture": ("furniture", lambda f: f, "is the input {src} (--furniture)"),
    "synth-out-holds-furniture": ("furniture", lambda f: f.parent, "holds the input {src} (--furniture)"),
}


@pytest.mark.parametrize("case", list(SOURCE_CASES))
def test_force_never_replaces_an_input_or_a_folder_above_one(case, interiorgs_src, run_cli, tmp_path):
    """import-interiorgs --out SRC --force deleted the source's files, and --out $(dirname SRC) --force the
    folder, the source and a user's file beside it; synth-scene --force did the same to its --furniture."""
    what, where, says = SOURCE_CASES[case]
    inputs = tmp_path / "inputs"
    src = shutil.copytree(interiorgs_src, inputs / "0001_1")
    usd = inputs / "usd" / "collision.usd"
    usd.parent.mkdir()
    usd.write_text("#usda 1.0\n")
    furniture = shutil.copytree(FURNITURE, inputs / "furniture")
    (inputs / "notes.txt").write_text("the user's, beside the inputs\n")
    given = {"src": src, "usd": usd, "furniture": furniture}[what]
    out = where(given)
    args = (["synth-scene", "--furniture", furniture] if what == "furniture"
            else ["import-interiorgs", src, *(["--collision-usd", usd] if what == "usd" else [])])
    line = refused(run_cli, [*args, "--out", out, "--force"], tmp_path, says.format(src=given))
    assert line == (f"error: --out: {out} {says.format(src=given)}; `{args[0]}` never writes over what it reads: "
                    "choose another --out")


# ---------------------------------------------------------------- one file: never in a run, never over the user's


@pytest.fixture(scope="module")
def made_predictions(made_run, tmp_path_factory) -> Path:
    """The oracle's predictions over made_run (and their record), outside it. Read-only."""
    from sagebench.settings.baseline import BaselineConfig
    from sagebench.stages.rollout import run_baseline

    out = tmp_path_factory.mktemp("made_predictions") / "oracle.jsonl"
    run_baseline(made_run, out, BaselineConfig(agent_name="oracle"))
    return out


def _file_writer(name: str, run: Path, out: Path, predictions: Path) -> list:
    return {"render": ["render", run, "--scene", "tiny", "--pose", "2,2,0", "--width", "8", "--height", "8",
                       "--out", out],
            "baseline": ["baseline", "--agent", "straight", "--run", run, "--out", out],
            "evaluate": ["evaluate", "--run", run, "--predictions", predictions, "--out", out],
            "rollout": ["rollout", "--run", run, "--policy", "straight", "--obs", "none", "--out", out]}[name]


FILE_WRITERS = ["render", "baseline", "evaluate", "rollout"]
IN_THE_RUN = "a sagebench run or export, where `{writer}` does not write"
FILE_OUTS = {  # where OUT is (made_run copied to tmp_path/run) -> what the one line says
    "manifest": (lambda tmp: tmp / "run" / "manifest.json", IN_THE_RUN),
    "shard": (lambda tmp: next((tmp / "run" / "episodes" / "tiny").glob("part-train-*.parquet")), IN_THE_RUN),
    "scene-xml": (lambda tmp: tmp / "run" / "scenes" / "tiny" / "scene.xml", IN_THE_RUN),
    "gaussians": (lambda tmp: tmp / "run" / "scenes" / "tiny" / "gaussians.ply", IN_THE_RUN),
    "a-new-file-in-the-run": (lambda tmp: tmp / "run" / "reports" / "mine.json", IN_THE_RUN),
    "a-link-into-the-run": (lambda tmp: (tmp / "link").symlink_to(tmp / "run" / "scenes") or tmp / "link" / "x.out",
                            IN_THE_RUN),
    "a-users-file": (lambda tmp: ((tmp / "mine.out").write_text("the user's\n"), tmp / "mine.out")[1],
                     "exists and sagebench did not write it; choose another --out, or --force to replace it"),
}


@pytest.mark.parametrize("where", list(FILE_OUTS))
@pytest.mark.parametrize("writer", FILE_WRITERS)
def test_a_file_output_never_lands_in_a_run_or_on_a_users_file(writer, where, made_run, made_predictions, run_cli,
                                                                 tmp_path):
    """--out RUN/manifest.json, a shard, scene.xml or gaussians.ply was overwritten by all four (and verify then
    failed), and a user's file silently: each is one line now, before any work, with --force too in a run."""
    run = copy_made(made_run, tmp_path / "run")
    make, says = FILE_OUTS[where]
    out = make(tmp_path)
    args = _file_writer(writer, run, out, made_predictions)
    refused(run_cli, args, tmp_path, says.format(writer=writer))
    if says == IN_THE_RUN:
        refused(run_cli, [*args, "--force"], tmp_path, says.format(writer=writer))


def test_sidecars_are_claimed_and_sagebench_s_own_outputs_are_replaced(made_run, made_predictions, run_cli, tmp_path):
    """A rollout's record and contact sheet beside OUT are claimed with it; an output sagebench wrote there (its
    content says so) is replaced without --force, a user's file only with it, never the predictions scored."""
    run = copy_made(made_run, tmp_path / "run")
    (tmp_path / "r_rollout.json").write_text("{}\n")
    refused(run_cli, ["baseline", "--agent", "straight", "--run", run, "--out", tmp_path / "r.jsonl"], tmp_path,
            "r_rollout.json: exists and sagebench did not write it")
    (tmp_path / "s_contact_sheet.png").write_bytes(b"\x89PNG\r\n\x1a\n the user's")
    refused(run_cli, ["rollout", "--run", run, "--policy", "straight", "--obs", "none", "--out", tmp_path / "s.jsonl"],
            tmp_path, "s_contact_sheet.png: exists and sagebench did not write it")
    refused(run_cli, ["evaluate", "--run", run, "--predictions", made_predictions, "--out", made_predictions,
                      "--force"], tmp_path, f"--out: {made_predictions} is the input {made_predictions} (--predictions)")
    for writer in FILE_WRITERS:
        out = tmp_path / f"{writer}.out"
        args = _file_writer(writer, run, out, made_predictions)
        assert run_cli(*args)[0] == 0 and run_cli(*args)[0] == 0, writer  # its own output: replaced
        out.write_text("now the user's\n")
        (tmp_path / f"{writer}_rollout.json").unlink(missing_ok=True)  # predictions are sagebench's by their record
        refused(run_cli, args, tmp_path, "exists and sagebench did not write it")
        assert run_cli(*args, "--force")[0] == 0, writer
    code, _, err = run_cli(*_file_writer("baseline", run, run / "baselines" / "straight.jsonl", made_predictions))
    assert code == 0, err  # the run's declared place for baselines
    assert not list(tmp_path.rglob(".*.sagebench.lock"))  # a results file's lock goes with its holder


def _hold_results(out: Path) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-c", "import sys, time\nfrom pathlib import Path\n"
                             "from sagebench.run_lock import results_lock\nwith results_lock(Path(sys.argv[1])):\n"
                             "    print('locked', flush=True)\n    time.sleep(600)\n", str(out)],
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline() == "locked\n"
    return proc


@pytest.mark.parametrize("writer", ["rollout", "baseline"])
def test_a_second_writer_of_a_results_file_is_refused(writer, made_run, run_cli, tmp_path):
    """Two rollouts into one results file both exited 0 and one policy's results were lost: a rollout holds its
    results file for its whole run, and the second is one line naming the first's pid."""
    out = tmp_path / "results.jsonl"
    holder = _hold_results(out)
    try:
        refused(run_cli, _file_writer(writer, made_run, out, out), tmp_path,
                f"{out}: another sagebench command (pid {holder.pid}) is writing this results file; wait for it to "
                "end or choose another")
    finally:
        holder.kill()
        holder.wait()
    code, _, err = run_cli(*_file_writer(writer, made_run, out, out))
    assert code == 0, err


# ---------------------------------------------------------------- import-sage-episodes claims its run


def test_import_sage_episodes_never_writes_a_run_another_command_holds(tiny_run, run_cli, tmp_path):
    sage = tmp_path / "sage"
    assert run_cli("export-sage", tiny_run, "--out", sage)[0] == 0
    run = shutil.copytree(tiny_run, tmp_path / "run")
    holder = _hold_lock(run)
    try:
        refused(run_cli, ["import-sage-episodes", sage / "tiny" / "trajectories_tiny.json", "--run", run], tmp_path,
                f"error: {run}: another sagebench command (pid {holder.pid}) is writing this run directory")
    finally:
        holder.kill()
        holder.wait()


def test_export_sage_goes_again_into_its_own_output_and_never_over_a_users_file(tiny_run, run_cli, tmp_path):
    mine = tmp_path / "mine" / "tiny" / "trajectories_tiny.json"
    mine.parent.mkdir(parents=True)
    mine.write_text('{"the": "user\'s"}\n')
    refused(run_cli, ["export-sage", tiny_run, "--out", tmp_path / "mine"], tmp_path,
            "is not empty and holds no export-sage output; use a new --out")
    out = tmp_path / "sage"
    assert run_cli("export-sage", tiny_run, "--out", out)[0] == 0
    first = snapshot(out)
    assert "sage_export.json" in first and "tiny/trajectories_tiny.json" in first
    code, _, err = run_cli("export-sage", tiny_run, "--out", out)
    assert code == 0, err
    assert snapshot(out) == first


# ---------------------------------------------------------------- a run folder is recognised by what it holds


def test_a_project_folder_of_its_config_and_inputs_takes_the_run(tiny_scene, run_cli, tmp_path):
    """`make demo`'s layout: run.toml (any header) and the input/ scenes it names, with out = ".". It was refused
    as "files that are not a sagebench run's" unless --force; a stray file of the user's still is."""
    project = tmp_path / "project"
    shutil.copytree(tiny_scene, project / "input" / "tiny")
    config = project / "run.toml"
    config.write_text("# my project\n" + TOML.format(scene="input/tiny", out="."))
    code, _, err = run_cli("-q", "run", config)
    assert code == 0, err
    assert (project / "manifest.json").is_file() and (project / "input" / "tiny" / "scene.json").is_file()
    (project / "notes.txt").write_text("mine\n")
    refused(run_cli, ["run", config], tmp_path, "holds files that are not a sagebench run's (notes.txt)")
    (project / "notes.txt").unlink()
    (project / "input" / "other.txt").write_text("mine\n")  # input/ holding more than the scenes named
    refused(run_cli, ["run", config], tmp_path, "holds files that are not a sagebench run's (input/)")


# ---------------------------------------------------------------- the finished lock and `cp -al`


def test_a_cp_al_copy_of_a_finished_run_takes_a_writer_and_the_original_is_untouched(tiny_run, run_cli, tmp_path):
    """Every finished run keeps .sagebench.lock; a `cp -al` copy shares it (2 links) and was refused as
    "hard-linked elsewhere". Nobody holds it: the copy's name is replaced by a fresh file, never written."""
    run = shutil.copytree(tiny_run, tmp_path / "run")
    args = ["--per-scene", "2", "--min-geodesic", "1"]
    assert run_cli("gen-trajectories", run, *args)[0] == 0
    lock = run / ".sagebench.lock"
    inode, before = lock.stat().st_ino, snapshot(run)
    subprocess.run(["cp", "-al", str(run), str(tmp_path / "copy")], check=True)
    assert lock.stat().st_nlink == 2
    code, _, err = run_cli("gen-trajectories", tmp_path / "copy", *args, "--seed", "1")
    assert code == 0, err
    assert (lock.stat().st_ino, lock.stat().st_nlink, snapshot(run)) == (inode, 1, before)
    assert (tmp_path / "copy" / ".sagebench.lock").stat().st_ino != inode
