"""Start-up stays cheap: `--help` (of the CLI and of every command) and refusing a bad scene import none of the
heavy libraries.

Checked in a fresh interpreter (this test process has imported everything already); the times themselves
are in `python -m benchmarks cli`.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

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
