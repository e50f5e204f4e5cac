"""Attacks on secrets, the run's integrity and the inputs that ended in tracebacks: each is refused in one line
(exit 2) or handled, and the tree is hashed before and after to show that nothing was written.

Companion of test_fuzz_inputs.py (damaged inputs) and test_run_folder.py (the run folder's claim); the last test
counts the attacks of all three.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from test_fuzz_inputs import snapshot

TOML = 'scenes = ["{scene}"]\nout = "{out}"\nseed = 0\n[gen_trajectories]\nper_scene = 2\nmin_geodesic_m = 1.0\n' \
       '[validate]\nframes_per_scene = 0\n[export_usd.colliders]\nmode = "fast"\n'


def _toml(path: Path, scene: Path, out: Path) -> Path:
    path.write_text(TOML.format(scene=scene, out=out))
    return path


def refused(run_cli, args: list, where: Path, expect: str) -> str:
    """Exit 2, one `error:` line holding `expect`, nothing on stdout, every file under `where` unchanged
    (links included: snapshot follows none, so the link's target is hashed where it lies)."""
    before = snapshot(where), sorted(str(p.relative_to(where)) for p in where.rglob("*"))
    code, out, err = run_cli(*args)
    lines = err.splitlines()
    assert (code, out, len(lines)) == (2, "", 1), (code, out, err)
    assert lines[0].startswith("error: ") and expect in lines[0], (expect, lines[0])
    assert (snapshot(where), sorted(str(p.relative_to(where)) for p in where.rglob("*"))) == before
    return lines[0]


# ---------------------------------------------------------------- the LLM key never reaches the disk or another host

KEY = "sk-test-5f3c9a7e1b2d4c6a8e0f"


def _llm_run(tmp_path: Path, scene: Path, url: str) -> Path:
    config = tmp_path / "llm.toml"
    text = TOML.format(scene=scene, out=tmp_path / "out") + f'[gen_trajectories.llm]\nbase_url = "{url}"\nmodel = "m"\n' \
        f'cache_dir = "{tmp_path / "cache"}"\nmax_attempts = 1\nbackoff_s = 0.01\n'
    config.write_text(text.replace("[gen_trajectories]\n", '[gen_trajectories]\ninstructions = "llm"\n'))
    return config


def _leaks(root: Path, *texts: str) -> list[str]:
    """Where KEY (or its tail) shows: files under `root`, and the texts given."""
    found = [str(p) for p in root.rglob("*") if p.is_file() and not p.is_symlink()
             and (KEY.encode() in p.read_bytes() or KEY[-12:].encode() in p.read_bytes())]
    return found + [t for t in texts if KEY in t or KEY[-12:] in t]


@pytest.mark.parametrize("how", ["401-echo", "redirect", "crash", "echo-in-answer"])
def test_the_api_key_reaches_no_file_log_or_other_host(how, fake_llm, tiny_scene, run_cli, tmp_path, monkeypatch):
    from fake_llm import Reply, answer

    elsewhere = fake_llm(lambda b, n: answer("Go to the table."))
    replies = {
        "401-echo": lambda b, n: Reply(401, f"invalid credentials: Bearer {KEY} (api_key={KEY})"),
        "redirect": lambda b, n: Reply(302, "moved", headers={"Location": elsewhere.url + "/chat/completions"}),
        "crash": lambda b, n: Reply(500, f"Traceback ...\nKeyError: 'Authorization: Bearer {KEY}'"),
        "echo-in-answer": lambda b, n: answer(f"Your key is {KEY}"),
    }
    server = fake_llm(replies[how])
    monkeypatch.setenv("SAGEBENCH_LLM_API_KEY", KEY)
    code, out, err = run_cli("run", _llm_run(tmp_path, tiny_scene, server.url))
    assert code == 1, err
    assert server.headers and all(h.get("Authorization") == f"Bearer {KEY}" for h in server.headers)
    assert elsewhere.headers == []  # a redirect is never followed: the key stays with its origin
    assert _leaks(tmp_path, out, err) == []
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    says = {"401-echo": "HTTP 401 invalid credentials: Bearer [redacted]", "crash": "Bearer [redacted]",
            "redirect": f"HTTP 302: the server redirects to {elsewhere.url.rsplit('/', 1)[0]} (redirects are not "
                        "followed", "echo-in-answer": "no high-level row came from the model"}[how]
    assert says in manifest["failed"]["tiny"]["message"], manifest["failed"]


def test_a_key_given_as_the_variable_name_is_refused_without_echoing_it(tiny_run, run_cli, tmp_path):
    out = tmp_path / "run"
    shutil.copytree(tiny_run, out)
    line = refused(run_cli, ["gen-trajectories", out, "--instructions", "llm", "--llm-base-url", "http://127.0.0.1:9/v1",
                             "--llm-model", "m", "--llm-api-key-env", KEY], tmp_path,
                   "--llm-api-key-env: takes the name of an environment variable holding the key")
    assert KEY not in line and KEY[-12:] not in line


def test_a_failed_llm_run_leaves_no_stale_shards_listed(fake_llm, tiny_scene, run_cli, tmp_path):
    from fake_llm import Reply

    config = tmp_path / "t.toml"
    config.write_text(TOML.format(scene=tiny_scene, out=tmp_path / "out"))
    assert run_cli("-q", "run", config)[0] == 0
    out = tmp_path / "out"
    assert list((out / "episodes" / "tiny").glob("part-*.parquet"))
    server = fake_llm(lambda b, n: Reply(503, "down"))
    code, _, err = run_cli("-q", "run", _llm_run(tmp_path, tiny_scene, server.url))
    assert code == 1, err
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["failed"]["tiny"]["stage"] == "gen_trajectories"
    assert not [k for k in manifest["files"] if k.startswith(("episodes/", "validation/"))]
    assert not (out / "episodes" / "tiny").exists() and not (out / "validation" / "tiny").exists()
    assert not (out / ".stamps" / "tiny" / "gen_trajectories.json").exists()
    code, stdout, _ = run_cli("verify", out)
    assert code == 1 and stdout.splitlines()[0].startswith("failed: tiny at gen_trajectories: ")
    assert [line for line in stdout.splitlines() if not line.startswith("failed: ")] == []


# ---------------------------------------------------------------- validate and verify read what they check


def copy_made(made_run: Path, to: Path) -> Path:
    """made_run copied as if this process had made it. It is built once per test run, by the first xdist worker to
    ask, and its lock file holds that worker's pid, which a command that takes the lock (and then refuses) replaces
    with its own: the copy holds ours, as when each worker made its own, so `refused` sees any other write."""
    shutil.copytree(made_run, to)
    (to / ".sagebench.lock").write_text(f"{os.getpid()}\n")
    return to


def _flip_geodesic(run: Path) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    shard = sorted((run / "episodes" / "tiny").glob("part-*.parquet"))[0]
    table = pq.read_table(shard)
    values = table.column("geodesic_distance").to_pylist()
    values[0] = 91.5
    pq.write_table(table.set_column(table.schema.get_field_index("geodesic_distance"), "geodesic_distance",
                                    pa.array(values)), shard)


def _without_records(damage):
    """`damage` to a run that an older sagebench's single-stage commands made: no manifest (nor the dataset card
    written with it), no stamps; what validate reads is then checked by its content alone."""
    return lambda run: (damage(run), (run / "manifest.json").unlink(), (run / "README.md").unlink(),
                        shutil.rmtree(run / ".stamps"))


VALIDATE_CASES = {  # damage to a copy of a made run -> what validate's one line says
    "train-shard-deleted": (lambda run: next((run / "episodes" / "tiny").glob("part-train-*.parquet")).unlink(),
                            "part-train-00000.parquet: listed in manifest.json but missing: the run is damaged"),
    "shard-value-flipped": (_flip_geodesic, "differs from the sha256 manifest.json records"),
    "stray-shard": (lambda run: shutil.copy(next((run / "episodes" / "tiny").glob("part-*.parquet")),
                                            run / "episodes" / "tiny" / "part-train-00009.parquet"),
                    "part-train-00009.parquet: not listed in manifest.json"),
    "usda-deleted": (lambda run: (run / "scenes" / "tiny" / "scene.usda").unlink(),
                     "scene.usda: missing; run `sagebench export-usd` on this run first"),
    "usda-garbage": (_without_records(lambda run: (run / "scenes" / "tiny" / "scene.usda").write_text("#usda 1.0\n(")),
                     "scene.usda: cannot open as USD"),
    "usda-no-objects": (_without_records(lambda run: (run / "scenes" / "tiny" / "scene.usda").write_text(
        '#usda 1.0\n(\n    defaultPrim = "World"\n)\n\ndef Xform "World"\n{\n}\n')), "scene.usda: no prim for object 1"),
    "usdc-deleted": (lambda run: (run / "scenes" / "tiny" / "geometry.usdc").unlink(),
                     "geometry.usdc: missing; run `sagebench export-usd`"),
    "usdc-garbage": (_without_records(lambda run: (run / "scenes" / "tiny" / "geometry.usdc").write_bytes(b"PXR-USDC")),
                     "scene.usda: "),
    "gaussians-a-directory": (lambda run: ((run / "scenes" / "tiny" / "gaussians.ply").unlink(),
                                           (run / "scenes" / "tiny" / "gaussians.ply").mkdir()),
                              "gaussians.ply: is a directory where sagebench writes a file"),
}


@pytest.mark.parametrize("case", list(VALIDATE_CASES))
def test_validate_checks_the_content_it_reads(case, made_run, run_cli, tmp_path):
    run = tmp_path / "run"
    copy_made(made_run, run)
    damage, expect = VALIDATE_CASES[case]
    damage(run)
    refused(run_cli, ["validate", run, "--frames-per-scene", "0"], tmp_path, expect)


def test_verify_checks_rows_and_the_usd_stage_beyond_the_hashes(made_run, run_cli, tmp_path):
    run = tmp_path / "run"
    copy_made(made_run, run)
    manifest = json.loads((run / "manifest.json").read_text())
    usda = run / "scenes" / "tiny" / "scene.usda"
    usda.write_text("#usda 1.0\n")
    shard = next(k for k in manifest["rows"])
    manifest["rows"][shard] += 1
    from sagebench.fileio import sha256_file

    manifest["files"]["scenes/tiny/scene.usda"] = sha256_file(usda)  # the hashes agree with the damaged files
    (run / "manifest.json").write_text(json.dumps(manifest))
    code, out, _ = run_cli("verify", run)
    assert code == 1
    assert out.splitlines() == [f"broken: {shard}: {manifest['rows'][shard] - 1} rows, the manifest records "
                                f"{manifest['rows'][shard]}",
                                f"broken: scenes/tiny/scene.usda: {usda}: no prim for object 1 (floor) under "
                                "/World/Objects; run export-usd again",
                                "broken: scenes/tiny/scene.usda: changed since export-usd wrote it (its stamp "
                                ".stamps/tiny/export_usd.json records another sha256); run export-usd again"]


def _npz_navigable(value) -> callable:
    def damage(run: Path) -> None:
        import numpy as np

        path = run / "scenes" / "tiny" / "topdown.npz"
        with np.load(path) as npz:
            arrays = {k: npz[k] for k in npz.files}
        arrays["navigable"] = np.full(arrays["navigable"].shape, value)
        np.savez(path, **arrays)
    return damage


@pytest.mark.parametrize("value, expect", [
    (float("nan"), "topdown.npz: navigable: navigable must hold 0/1/2 only: "),
    (0, "topdown.npz: navigable: no navigable cell"),
    (3, "topdown.npz: navigable: navigable must hold 0/1/2 only: "),
])
def test_a_navigable_map_of_nan_or_nothing_is_refused(value, expect, tiny_run, run_cli, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    _npz_navigable(value)(run)
    refused(run_cli, ["gen-trajectories", run, "--per-scene", "2"], tmp_path, expect)
    refused(run_cli, ["validate", run, "--frames-per-scene", "0"], tmp_path, expect)


def test_build_scene_refuses_an_agent_that_fits_nowhere(tiny_scene, run_cli, tmp_path):
    refused(run_cli, ["build-scene", tiny_scene, "--out", tmp_path / "run", "--agent-radius", "50"], tmp_path,
            "agent.radius: an agent of radius 50 m fits nowhere on the floor: no navigable cell")
    assert not (tmp_path / "run").exists()


# ---------------------------------------------------------------- what used to end in a traceback: one line now


def _spec_text(edit) -> str:
    from test_fuzz_inputs import SPEC

    return edit(json.dumps(SPEC, indent=1))


def _sparse(name: str, size: int):
    def make(scene: Path) -> None:
        path = scene / name
        path.unlink()
        with open(path, "wb") as fh:
            fh.truncate(size)  # a hole: nothing is written, the file reads as zeros
    return make


def _ply_claiming(faces: int):
    def make(scene: Path) -> None:
        (scene / "meshes" / "cabinet.ply").write_bytes(
            b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            b"property float z\nelement face %d\nproperty list uchar int vertex_indices\nend_header\n" % faces)
    return make


def _dense_glb(scene: Path) -> None:
    import trimesh

    trimesh.creation.icosphere(subdivisions=7).export(scene / "meshes" / "table.glb")  # 327,680 faces


SCENE_TRACEBACKS = {  # damage to a copy of the tiny scene -> check-scene's and build-scene's line
    "int-5000-digits": (lambda s: (s / "scene.json").write_text(_spec_text(lambda t: t.replace(
        '"instance_id": 1,', '"instance_id": ' + "9" * 5000 + ",", 1))),
        "scene.json: malformed JSON: Exceeds the limit (4300 digits) for integer string conversion"),
    "nul-in-category": (lambda s: (s / "scene.json").write_text(_spec_text(lambda t: t.replace(
        '"category": "table"', '"category": "ta\\u0000ble"'))),
        "scene.json: objects[2].category: String should match pattern"),
    "newline-in-attribute": (lambda s: (s / "scene.json").write_text(_spec_text(lambda t: t.replace(
        '"colour": "red"', '"colour": "red\\nblue"'))), "scene.json: objects[2].attributes.colour: String should match"),
    "sparse-2gb-mesh": (_sparse("meshes/table.glb", 2 << 30),
                        "objects[2].mesh: mesh 'table.glb' is 2.0 GiB, over the budget of 1 GiB per mesh file"),
    "4m-face-header": (_ply_claiming(4_000_000),
                       "objects[4].mesh: mesh 'cabinet.ply' has 4,000,000 faces, over the budget of 200,000"),
    "327k-face-mesh": (_dense_glb, "objects[2].mesh: mesh 'table.glb' has 327,680 faces, over the budget of 200,000"),
    "gaussians-a-directory": (lambda s: (s / "gaussians.ply").mkdir(),
                              "gaussians.ply: is not a PLY file (a directory or a broken link)"),
}


@pytest.mark.parametrize("case", list(SCENE_TRACEBACKS))
def test_scene_inputs_that_raised_are_one_line(case, tiny_scene, run_cli, tmp_path):
    scene = tmp_path / "scene"
    shutil.copytree(tiny_scene, scene)
    damage, expect = SCENE_TRACEBACKS[case]
    damage(scene)
    refused(run_cli, ["check-scene", scene], tmp_path, expect)
    refused(run_cli, ["build-scene", scene, "--out", tmp_path / "run"], tmp_path, expect)


TOML_TRACEBACKS = {
    "int-5000-digits": ("seed = " + "9" * 5000 + "\n", "malformed TOML: Exceeds the limit (4300 digits)"),
    "nested-100000": ("a = " + "[" * 100_000 + "]" * 100_000 + "\n", "malformed TOML: nested too deeply"),
    "not-utf8": ("\udcff", "cannot read: not UTF-8 text"),
}


@pytest.mark.parametrize("case", list(TOML_TRACEBACKS))
def test_run_tomls_that_raised_are_one_line(case, tiny_scene, run_cli, tmp_path):
    text, expect = TOML_TRACEBACKS[case]
    config = tmp_path / "run.toml"
    config.write_bytes((f'scenes = ["{tiny_scene}"]\nout = "out"\n' + text).encode("utf-8", "surrogateescape"))
    refused(run_cli, ["run", config], tmp_path, f"run.toml: {expect}")


def test_predictions_too_long_to_score_are_refused_before_they_are_read(tiny_run, run_cli, tmp_path):
    from sagebench.episodes.load import read_trajectories

    episode = read_trajectories(tiny_run / "episodes" / "tiny")[0].episode_ids[0]
    for poses, expect in ((1_000_000, "pred.jsonl:1: the line is "), (10_001, "pred.jsonl:1: poses: List should have "
                                                                                "at most 10000 items")):
        line = json.dumps({"episode_id": episode, "poses": [[1.0, 1.0, 0.0, 0.0]] * poses, "stopped": True})
        (tmp_path / "pred.jsonl").write_text(line + "\n")
        refused(run_cli, ["evaluate", "--run", tiny_run, "--predictions", tmp_path / "pred.jsonl"], tmp_path, expect)


def test_a_semantic_map_that_is_a_directory_is_one_line(tiny_run, run_cli, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    (run / "scenes" / "tiny" / "semantic_map.json").unlink()
    (run / "scenes" / "tiny" / "semantic_map.json").mkdir()
    refused(run_cli, ["gen-trajectories", run], tmp_path, "semantic_map.json: is a directory where sagebench writes a "
                                                        "file; run `sagebench build-scene` on this run again")


@pytest.mark.parametrize("delay", [0.0, 0.2, 0.5, 1.0, 1.8])
def test_ctrl_c_in_the_first_seconds_of_run_is_one_line_and_writes_nothing(delay, tiny_scene, tmp_path):
    """Ctrl-C `delay` s after sagebench's own imports began (pydantic's core library mapped: the interpreter's
    start, before any sagebench code runs, is Python's), while the CLI imports, loads the config and starts: one
    line, no partial file, and what is left is what the interrupt line promises, stages to go on from."""
    import signal
    import time

    from signals import as_from_a_terminal

    config = _toml(tmp_path / "run.toml", tiny_scene, tmp_path / "out")
    proc = subprocess.Popen([sys.executable, "-m", "sagebench", "run", str(config)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, preexec_fn=as_from_a_terminal)
    maps, deadline = Path(f"/proc/{proc.pid}/maps"), time.monotonic() + 120
    while proc.poll() is None and time.monotonic() < deadline and b"pydantic_core" not in maps.read_bytes():
        time.sleep(0.005)
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=300)
    if proc.returncode == 0:
        pytest.fail(f"the run ignored Ctrl-C after {delay} s")
    # -SIGINT: Python ends itself by the signal when one reached code that ran under PyRun (a shell reports 130)
    assert proc.returncode in (130, -signal.SIGINT), (proc.returncode, err)
    *before, last = err.splitlines()
    assert last.startswith("error: interrupted") and "Traceback" not in err, err
    # on a fast machine a stage may finish first: its "ran" line (and its warnings) may come before the interrupt's
    assert not [line for line in before if line.startswith("error")], err
    out = tmp_path / "out"
    written = [p for p in out.rglob("*") if p.is_file() and p.name != ".sagebench.lock"] if out.exists() else []
    assert not [p for p in written if ".tmp" in p.name], written  # nothing partial is left
    if written:  # a stage got as far as writing (on a loaded machine even without its "ran" line yet)
        code = subprocess.run([sys.executable, "-m", "sagebench", "-q", "run", str(config)], capture_output=True,
                              text=True, timeout=600)
        assert code.returncode == 0, code.stderr  # "run again to go on from them": the run finishes on top of it


SWALLOWS_CTRL_C = """
import signal, sys
from importlib.abc import MetaPathFinder

class Swallow(MetaPathFinder):  # a library that imports under `except BaseException`, as trimesh's optional parts do
    def find_spec(self, name, path=None, target=None):
        if name == "pydantic_core":
            sys.meta_path.remove(self)
            try:
                signal.raise_signal(signal.SIGINT)  # Ctrl-C, raised in the handler at once
            except BaseException:
                pass
        return None

sys.meta_path.insert(0, Swallow())
sys.argv[0] = "sagebench"
from sagebench.__main__ import entry
entry()
"""


def test_ctrl_c_a_library_swallows_while_the_cli_imports_still_ends_the_run(tiny_scene, tmp_path):
    """CI once sent Ctrl-C as pydantic's core loaded and the run went on to finish with exit 0: a Ctrl-C caught
    by a library while the command imports is noted and ends it in one line, before anything is written."""
    from signals import as_from_a_terminal

    config = _toml(tmp_path / "run.toml", tiny_scene, tmp_path / "out")
    proc = subprocess.run([sys.executable, "-c", SWALLOWS_CTRL_C, "run", str(config)], capture_output=True,
                          text=True, timeout=600, preexec_fn=as_from_a_terminal)
    assert (proc.returncode, proc.stderr, proc.stdout) == (130, "error: interrupted: nothing was written\n", "")
    assert not (tmp_path / "out").exists()


CTRL_C_AT_IMPORT = """
import os, signal, sys
module, fired = sys.argv[1:3]
def ctrl_c_at(event, args):  # Ctrl-C as `module` starts to load, once
    if event == "import" and args[0] == module and not os.path.exists(fired):
        open(fired, "w").close()
        os.kill(os.getpid(), signal.SIGINT)
sys.addaudithook(ctrl_c_at)
sys.argv[0:3] = ["sagebench"]
from sagebench.__main__ import entry
entry()
"""


@pytest.mark.slow  # a run per library, for CI (make test-slow); the timed Ctrl-Cs above run in make test
@pytest.mark.parametrize("module", ["pxr.Gf", "pxr.Sdf", "pxr.UsdPhysics", "trimesh", "mujoco", "numba",
                                    "scipy.spatial", "pyarrow.parquet", "cv2"])
def test_ctrl_c_as_each_heavy_library_loads_is_one_line(module, tiny_scene, tmp_path):
    """CI sent Ctrl-C 1.8 s into a run as USD loaded the modules of its libraries: USD's loader printed it as a
    'Warning' with a Traceback. Ctrl-C at the first import of each library the run's own process loads (its pool
    workers end at a Ctrl-C without a word), wherever the run is then: one interrupt line, no traceback or library
    warning, nothing partial."""
    import signal

    from signals import as_from_a_terminal

    config, fired = _toml(tmp_path / "run.toml", tiny_scene, tmp_path / "out"), tmp_path / "fired"
    proc = subprocess.run([sys.executable, "-c", CTRL_C_AT_IMPORT, module, str(fired), "run", str(config)],
                          capture_output=True, text=True, timeout=600, preexec_fn=as_from_a_terminal)
    assert fired.exists(), f"the run never imported {module}"
    assert proc.returncode in (130, -signal.SIGINT), (proc.returncode, proc.stderr)
    last = proc.stderr.splitlines()[-1]
    assert last.startswith("error: interrupted") and "Traceback" not in proc.stderr and "Warning:" not in proc.stderr, \
        proc.stderr
    out = tmp_path / "out"
    assert not [p for p in out.rglob("*") if ".tmp" in p.name] if out.exists() else True


# ---------------------------------------------------------------- the count


FOLDER_CASES = ["force-beside-users-files", "artist-scene-under-out", "input-inside-out", "hidden-files-survive",
                "out-is-a-file", "out-is-a-dangling-link", "second-writer", "failed-command-leaves-nothing",
                "read-only-parent", "read-only-out", "mesh-mode-000", "meshes-dir-mode-000", "scene-json-mode-000"]
CASES = [*FOLDER_CASES, *(f"key-{how}" for how in ("401-echo", "redirect", "crash", "echo-in-answer")), "key-as-variable-name",
         "failed-llm-run-stale-shards", *(f"validate-{c}" for c in VALIDATE_CASES), "verify-rows-and-usd",
         "navigable-nan", "navigable-zero", "navigable-3", "agent-radius-50",
         *(f"scene-{c}" for c in SCENE_TRACEBACKS), *(f"toml-{c}" for c in TOML_TRACEBACKS),
         "predictions-1e6-poses", "predictions-10001-poses", "semantic-map-a-directory",
         *(f"ctrl-c-{d}" for d in (0.0, 0.2, 0.5, 1.0, 1.8)), "ctrl-c-swallowed-while-importing"]


def test_the_reliability_suite_adds_its_cases_to_the_damaged_inputs():
    """This file's attacks, each a distinct case, on top of test_fuzz_inputs' 250 or more damaged inputs."""
    from test_fuzz_inputs import GLTF_CASES, MESH_CASES, PLY_CASES, PREDICTION_CASES, RUN_CASES, SCENE_CASES, TOML_CASES
    from test_run_folder import EXPORT_OUTS, EXPORTERS, LOCKS, WRITERS

    cases = [*(f"lock-{lock}-{writer}" for lock in LOCKS for writer in WRITERS),
             *(f"users-folder-{writer}" for writer in WRITERS),
             *(f"{exporter}-into-{where}" for exporter in EXPORTERS for where in EXPORT_OUTS),
             *CASES]  # test_run_folder.py's and this file's
    assert len(set(cases)) == len(cases) >= 120
    before = len(SCENE_CASES) + len(PLY_CASES) + len(MESH_CASES) + len(GLTF_CASES) + len(RUN_CASES) + \
        len(PREDICTION_CASES) + len(TOML_CASES)
    assert before >= 250 and before + len(cases) >= 370
