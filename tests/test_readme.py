"""The README's examples stay true: its run config validates and every command it documents exists."""

from __future__ import annotations

import re
from pathlib import Path

from sagebench.pipeline.config import load_run_config

README = (Path(__file__).resolve().parents[1] / "README.md").read_text()


def test_readme_run_config_example_is_valid(tmp_path):
    (block,) = re.findall(r"```toml\n(.*?)```", README, flags=re.S)
    path = tmp_path / "run.toml"
    path.write_text(block)
    config = load_run_config(path)
    assert config.workers == 2 and config.gen_trajectories.per_scene == 200
    assert config.export_usd.colliders.coacd.threshold == 0.05 and config.validate_.frames_per_scene == 3
    assert (config.export_usd.colliders.mode, config.export_usd.colliders.max_parts) == ("balanced", 32)


def test_every_documented_command_exists(run_cli):
    import typer.main

    from sagebench.cli import app

    documented = set(re.findall(r"^### `sagebench ([a-z-]+)", README, flags=re.M))
    documented |= set(re.findall(r"`sagebench ([a-z-]+)[ `]", README))
    commands = set(typer.main.get_command(app).commands)
    assert documented - commands == set()
    assert commands - documented == set(), "commands missing from the README"
