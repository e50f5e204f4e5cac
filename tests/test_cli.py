"""The command line: help texts, the demo-scene command, the schemas command."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from sagebench.cli import app


def _commands() -> list[str]:
    import typer.main

    return sorted(typer.main.get_command(app).commands)


def test_help_lists_commands(run_cli):
    code, out, _ = run_cli("--help")
    assert code == 0
    for name in _commands():
        assert name in out


def test_every_command_help_says_what_it_reads_and_writes(run_cli):
    for name in _commands():
        code, out, _ = run_cli(name, "--help")
        assert code == 0
        assert "Reads" in out and "Writes" in out, name


def test_synth_scene_writes_a_loadable_scene(run_cli, tmp_path):
    code, out, err = run_cli("synth-scene", "--seed", "3", "--out", tmp_path / "s3")
    assert code == 0, err
    assert "5 rooms" in out
    code, out, err = run_cli("check-scene", tmp_path / "s3")
    assert code == 0, err
    assert out.startswith("scene demo_apartment_3: 5 rooms")


def _tree(root: Path) -> dict[str, bytes | None]:
    return {p.relative_to(root).as_posix(): None if p.is_dir() else p.read_bytes() for p in sorted(root.rglob("*"))}


@pytest.mark.parametrize("make, says", [
    (lambda out: (out.mkdir(), (out / "notes.txt").write_text("mine")),
     "is not empty and not a scene written by `sagebench synth-scene`"),
    (lambda out: (out.mkdir(), (out / ".x.old").write_text("mine")),
     "is not empty and not a scene written by `sagebench synth-scene`"),
    (lambda out: out.write_text("mine"), "exists and is not a directory"),
])
def test_synth_scene_refuses_to_replace_a_users_files(run_cli, tmp_path, make, says):
    out = tmp_path / "target"
    make(out)
    before = _tree(tmp_path)
    code, stdout, err = run_cli("synth-scene", "--seed", "3", "--out", out)
    assert code == 2 and stdout == ""
    assert err.splitlines() == [f"error: {out}: --out: {says}; choose another --out (or --force to replace it)"]
    assert _tree(tmp_path) == before
    code, _, err = run_cli("synth-scene", "--seed", "3", "--out", out, "--force")
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["meshes", "scene.json"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["target"]


def test_synth_scene_replaces_an_empty_directory_or_its_own_scene(run_cli, tmp_path, demo_scene_dir):
    out = tmp_path / "s"
    out.mkdir()
    assert run_cli("synth-scene", "--seed", "3", "--out", out)[0] == 0
    assert run_cli("synth-scene", "--seed", "0", "--out", out)[0] == 0  # its own scene, another seed: replaced
    assert _tree(out) == _tree(demo_scene_dir)
    (out / "meshes" / "extra.ply").write_bytes(b"")  # no longer only what synth-scene wrote
    assert run_cli("synth-scene", "--seed", "0", "--out", out)[0] == 2


def test_schemas_command_writes_every_schema(run_cli, tmp_path):
    code, out, _ = run_cli("schemas", "--out", tmp_path)
    assert code == 0
    schema = json.loads((tmp_path / "scene.schema.json").read_text())
    assert schema["title"] == "SceneSpec"


def test_demo_runs_the_whole_pipeline_and_verifies(run_cli, tmp_path):
    out = tmp_path / "demo"
    code, stdout, err = run_cli("-q", "demo", "--out", out)
    assert code == 0, stdout + err
    assert re.search(r"1 scenes, \d{3,} episodes, 1 scenes complete in", stdout), stdout
    for rel in ("run.toml", "manifest.json", "scenes/demo_apartment_0/topdown.png", "scenes/demo_apartment_0/scene.usda",
                "episodes/demo_apartment_0/part-train-00000.parquet", "episodes/demo_apartment_0/part-val_seen-00000.parquet",
                "validation/demo_apartment_0/report.json",
                "README.md",
                "baselines/oracle.jsonl"):
        assert (out / rel).is_file(), rel
    overall = json.loads((out / "baselines" / "oracle_results.json").read_text())["overall"]
    assert overall["sr"] == 1.0 and overall["icp"] < 0.01 and overall["csr"] == 1.0  # ICP measured by the simulator
    code, stdout, _ = run_cli("verify", out)
    assert code == 0 and stdout.startswith("ok:")


def test_version_prints_the_package_version(run_cli):
    from sagebench import __version__

    assert run_cli("--version") == (0, f"sagebench {__version__}\n", "")


def test_global_flags_are_accepted_after_the_command(run_cli, tmp_path):
    from sagebench.cli import hoist_global_flags

    assert hoist_global_flags(["export-usd", "r", "-q", "--debug", "--", "--quiet"]) == \
        ["-q", "--debug", "export-usd", "r", "--", "--quiet"]
    code, out, err = run_cli("synth-scene", "--out", tmp_path / "s", "--seed", "1", "--quiet")
    assert code == 0 and (tmp_path / "s" / "scene.json").is_file(), err
    code, _, err = run_cli("check-scene", tmp_path / "nope", "--quiet")
    assert code == 2 and err == f"error: {tmp_path / 'nope'}: no scene.json in this directory\n"


def test_shell_completion_completes_command_names():
    import os
    import subprocess
    import sys

    env = {**os.environ, "_SAGEBENCH_COMPLETE": "complete_bash", "COMP_WORDS": "sagebench export-", "COMP_CWORD": "1"}
    done = subprocess.run([sys.executable, "-m", "sagebench"], env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["export-usd", "export-vlnce", "export-training"]
