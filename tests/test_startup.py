"""Start-up stays cheap: `--help` (of the CLI and of every command) and refusing a bad scene import none of the
heavy libraries.

Checked in a fresh interpreter (this test process has imported everything already); the times themselves
are in `python -m benchmarks cli`.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import pytest

from sagebench.threads import available_cores

HEAVY = ("trimesh", "scipy", "numba", "mujoco", "pyarrow", "pxr", "coacd", "ray", "cv2", "shapely")

PROBE = """
import json, sys
from sagebench.cli import main
try:
    main(sys.argv[1:])
except SystemExit as exc:
    code = exc.code
print(json.dumps({"code": code, "heavy": sorted(m for m in %r if m in sys.modules)}))
""" % (HEAVY,)


def _probe(*args: str) -> dict:
    proc = subprocess.run([sys.executable, "-c", PROBE, *args], capture_output=True, text=True, timeout=120)
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("args, code", [
    (("--help",), 0),
    (("build-scene", "{bad}", "--out", "{run}"), 2),
    (("check-scene", "{bad}"), 2),
])
def test_help_and_a_bad_scene_import_no_heavy_library(args, code, tmp_path):
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "scene.json").write_text('{"scene_id": 3}')
    got = _probe(*(a.format(bad=bad, run=tmp_path / "run") for a in args))
    assert got == {"code": code, "heavy": []}


def test_the_probe_sees_a_heavy_import(tmp_path):
    """A command that needs trimesh does import it, so an empty list above is not a blind probe."""
    got = _probe("synth-scene", "--seed", "0", "--out", str(tmp_path / "s"))
    assert got["code"] in (0, None) and "trimesh" in got["heavy"]


EVERY_HELP = """
import json, sys
import typer.main
from sagebench.cli import app, main
for name in typer.main.get_command(app).commands:
    try:
        main([name, "--help"])
    except SystemExit:
        pass
print(json.dumps(sorted(m for m in %r if m in sys.modules)))
""" % (HEAVY,)


def test_every_commands_help_imports_no_heavy_library():
    """A command's --help is made from its settings model alone (sagebench/settings/ imports pydantic only), not
    from the stage that runs it."""
    proc = subprocess.run([sys.executable, "-c", EVERY_HELP], capture_output=True, text=True, timeout=120)
    assert json.loads(proc.stdout.strip().splitlines()[-1]) == []


# ---------------------------------------------------------------- what a real command loads (issue 40)

THREAD_VARS = ("OMP_WAIT_POLICY", "NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
RUN_PROBE = """
import json, os, sys
seen = {}
class Watch:  # notes the thread settings at the moment numba (whose pool is libgomp's) is first imported
    def find_spec(self, name, path=None, target=None):
        if name == "numba" and not seen:
            seen.update(wait=os.environ.get("OMP_WAIT_POLICY"), threads=os.environ.get("NUMBA_NUM_THREADS"))
sys.meta_path.insert(0, Watch())
from sagebench.cli import main
try:
    main(sys.argv[1:])
except SystemExit as exc:
    code = exc.code
print(json.dumps({"code": code, "numba": seen, "heavy": sorted({m.split(".")[0] for m in sys.modules} & %r),
                  "generators": "sagebench.instructions.high_level" in sys.modules}))
""" % (set(HEAVY) | {"pandas"},)


def _run_probe(*args) -> tuple[dict, dict[str, float]]:
    """What `sagebench ARGS` loaded in a fresh interpreter without thread settings of its own, and from
    `python -X importtime` each heavy library's cumulative import seconds (for the failure message)."""
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARS}
    proc = subprocess.run([sys.executable, "-X", "importtime", "-c", RUN_PROBE, "-q", *map(str, args)],
                          capture_output=True, text=True, timeout=300, env=env)
    cost: dict[str, float] = {}
    for line in proc.stderr.splitlines():
        parts = line.removeprefix("import time:").split("|")
        if len(parts) == 3 and parts[2].strip().split(".")[0] in (*HEAVY, "pandas") and parts[1].strip().isdigit():
            name = parts[2].strip().split(".")[0]
            cost[name] = max(cost.get(name, 0.0), int(parts[1]) / 1e6)
    assert proc.stdout.strip(), proc.stderr[-2000:]
    return json.loads(proc.stdout.strip().splitlines()[-1]), cost


def test_evaluate_of_measured_predictions_loads_no_simulator(tiny_run):
    """The oracle's predictions carry the simulator's c(t): evaluate replays nothing, so it loads neither MuJoCo nor
    pyarrow.dataset's pandas (together 0.7-1.3 of its 2.2 CPU-s on the tiny run); numba starts waiting passively."""
    got, cost = _run_probe("evaluate", "--run", tiny_run, "--predictions", tiny_run / "baselines" / "oracle.jsonl")
    assert got["code"] in (0, None)
    assert not {"mujoco", "pandas", "pxr", "trimesh", "coacd", "ray"} & set(got["heavy"]), cost
    assert got["numba"] == {"wait": "PASSIVE", "threads": str(available_cores())}


def test_validate_loads_no_instruction_generator_and_waits_passively(tiny_run, tmp_path):
    """validate reads instructions, it writes none: the generators (scipy's max-flow, shapely) stay unloaded, and its
    OpenMP threads sleep when idle (5.53 CPU-s spinning against 3.99 passive, issue 40)."""
    run = tmp_path / "run"
    shutil.copytree(tiny_run, run)
    got, cost = _run_probe("validate", run)
    assert got["code"] in (0, 1, None)
    assert not got["generators"] and not {"trimesh", "coacd", "ray"} & set(got["heavy"]), cost
    assert got["numba"] == {"wait": "PASSIVE", "threads": str(available_cores())}


def test_a_command_without_share_cores_waits_passively(tiny_scene):
    """check-scene (numba's kernels, no share_cores of its own) still starts numba with the passive wait."""
    got, _ = _run_probe("check-scene", tiny_scene)
    assert got["code"] in (0, None) and got["numba"] == {"wait": "PASSIVE", "threads": str(available_cores())}


API_PROBE = """
import json, os
from sagebench.stages.evaluate import evaluate  # a program using the Python API: numba loads with it
import numba
print(json.dumps([os.environ.get("OMP_WAIT_POLICY"), numba.config.NUMBA_NUM_THREADS]))
"""


def test_the_python_api_waits_passively():
    """Importing sagebench sets the process defaults (a user's own OMP_WAIT_POLICY wins: test_threads.py)."""
    env = {k: v for k, v in os.environ.items() if k not in THREAD_VARS}
    proc = subprocess.run([sys.executable, "-c", API_PROBE], capture_output=True, text=True, timeout=120, env=env)
    assert json.loads(proc.stdout.strip().splitlines()[-1]) == ["PASSIVE", available_cores()], proc.stderr[-2000:]
