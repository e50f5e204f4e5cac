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


@pytest.mark.slow  # the README's first command, end to end on the demo apartment: CI runs it (make test-slow)
def test_demo_runs_the_whole_pipeline_and_verifies(run_cli, tmp_path):
    out = tmp_path / "demo"
    code, stdout, err = run_cli("-q", "demo", "--out", out)
    assert code == 0, stdout + err
    assert re.search(r"1 scenes, \d{3,} episodes, 1 scenes complete in", stdout), stdout
    for rel in ("run.toml", "manifest.json", "scenes/demo_apartment_0/topdown.png", "scenes/demo_apartment_0/scene.usda",
                "episodes/demo_apartment_0/part-train-00000.parquet", "episodes/demo_apartment_0/part-val_seen-00000.parquet",
                "reports/demo_apartment_0/report.json",
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
    assert code == 2 and err == f"error: {tmp_path / 'nope'}: does not exist\n"


def test_shell_completion_completes_command_names():
    import os
    import subprocess
    import sys

    env = {**os.environ, "_SAGEBENCH_COMPLETE": "complete_bash", "COMP_WORDS": "sagebench export-", "COMP_CWORD": "1"}
    done = subprocess.run([sys.executable, "-m", "sagebench"], env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["export-usd", "export-vlnce", "export-habitat", "export-training", "export-sage"]


INPUT_OPTIONS = {"--run", "--config", "--predictions", "--furniture", "--collision-usd"}  # options naming a file a command reads


def _input_params():
    """(command name, click parameter) of every path a command reads: its Path arguments and INPUT_OPTIONS."""
    import typer.main

    from sagebench.cli import app

    group = typer.main.get_command(app)
    for name, command in sorted(group.commands.items()):
        for param in command.params:
            is_path = "Path" in str(param.type_descriptor.annotation)
            if param.param_type_name == "argument" and is_path or INPUT_OPTIONS & set(param.opts):
                yield name, param


def test_every_input_path_is_checked_by_the_one_existing_helper():
    from sagebench.cli import existing

    params = list(_input_params())
    assert len(params) >= 14
    for name, param in params:
        callback = param.callback  # typer wraps it, keeping its name and module
        assert callback is existing or (callback.__module__, callback.__qualname__) == ("sagebench.cli", "existing"), \
            f"{name} {param.name}"


@pytest.mark.parametrize("argv", [
    ["check-scene", "{nope}"], ["build-scene", "{nope}", "--out", "{out}"], ["gen-trajectories", "{nope}"],
    ["export-usd", "{nope}"], ["validate", "{nope}"], ["export-vlnce", "{nope}", "--out", "{out}"],
    ["render", "{nope}", "--scene", "s", "--pose", "0,0,0", "--out", "{out}"], ["run", "{nope}"],
    ["verify", "{nope}"], ["synth-scene", "--out", "{out}", "--furniture", "{nope}"],
    ["evaluate", "--run", "{nope}", "--predictions", "{nope}"], ["baseline", "--agent", "oracle", "--run", "{nope}",
                                                                  "--out", "{out}"],
    ["rollout", "--run", "{nope}", "--out", "{out}"], ["export-training", "{nope}", "--out", "{out}"],
    ["import-interiorgs", "{nope}", "--out", "{out}"], ["export-sage", "{nope}", "--out", "{out}"],
    ["import-sage-episodes", "{nope}", "--run", "{nope}"], ["report", "{nope}", "--out", "{out}"],
    ["report", "{tmp}", "--predictions", "{tmp}", "--predictions", "{nope}", "--out", "{out}"],
])
def test_a_path_that_does_not_exist_is_the_one_error_and_nothing_is_written(run_cli, tmp_path, argv):
    nope = tmp_path / "typo" / "runs" / "r1"
    code, out, err = run_cli(*[a.format(nope=nope, out=tmp_path / "out", tmp=tmp_path) for a in argv])
    assert (code, out, err) == (2, "", f"error: {nope}: does not exist\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.parametrize(("words", "want"), [
    ("sagebench export-usd run --colliders ", ["quality", "balanced", "fast"]),
    ("sagebench export-usd run --colliders f", ["fast"]),
    ("sagebench export-usd run --gaussians ", ["particlefield", "nurec"]),
    ("sagebench gen-trajectories run --instructions ", ["template", "llm", "none"]),
    ("sagebench export-vlnce run --split val_", ["val_seen", "val_unseen"]),
    ("sagebench baseline --agent ", ["oracle", "straight", "random", "stationary", "explorer"]),
])
def test_shell_completion_completes_option_values(words, want):
    """The values come from the settings models' Literal fields (and the splits), read when the shell asks."""
    import os
    import subprocess
    import sys

    cword = str(len(words.split()) - (0 if words.endswith(" ") else 1))
    env = {**os.environ, "_SAGEBENCH_COMPLETE": "complete_bash", "COMP_WORDS": words, "COMP_CWORD": cword}
    done = subprocess.run([sys.executable, "-m", "sagebench"], env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == want
