"""The README and docs stay true: the run config of docs/run.md validates, the README names every command and
only real ones, and stays a newcomer's page (at most 300 lines) whose links to docs/ resolve."""

from __future__ import annotations

import re
from pathlib import Path

from sagebench.pipeline.config import load_run_config

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def test_the_documented_run_config_is_valid(tmp_path):
    (block,) = re.findall(r"```toml\n(.*?)```", (ROOT / "docs" / "run.md").read_text(), flags=re.S)
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


def test_the_readme_is_short_and_its_links_resolve():
    assert len(README.splitlines()) <= 300, "move detail into a docs/ page"
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    for page in pages:
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", page.read_text()):
            if not target.startswith(("http://", "https://")):
                assert (page.parent / target).exists(), f"{page.relative_to(ROOT)}: broken link {target}"


def test_the_score_table_has_a_row_block_per_task_with_real_agents():
    """Each task's baselines are in the README (the oracle on each goal task, the explorer and random walk on
    nogoal, the stationary agent on every task), by agents `sagebench baseline` has, and the no-goal threshold the
    README and docs/tasks/nogoal.md state is the one evaluate applies."""
    import typing

    from sagebench.settings.baseline import BaselineConfig
    from sagebench.settings.shared import TASKS, TaskMetricConfig

    agents = set(typing.get_args(BaselineConfig.model_fields["agent_name"].annotation))
    section = README.split("## Scores on the demo")[1].split("\n## ")[0]
    rows = re.findall(r"^\| (\w+) \| (\w+) \| [0-9.]+ \|", section, flags=re.M)  # goal tasks: | task | agent |
    rows += [("nogoal", a) for a in re.findall(r"^\| (\w+) \| [0-9.]+ \| [0-9.]+ \| [0-9.]+ \| [0-9.]+ \| [0-9.]+ \| "
                                               r"[0-9.]+ \| [0-9.]+ \|$", section, flags=re.M)]
    rows += [("vln", a) for a in re.findall(r"^\| (\w+) \|(?: [0-9.]+ \|){10}$", section, flags=re.M)]
    assert {a for _, a in rows} <= agents
    wanted = {(t, "stationary") for t in TASKS} | {(t, "oracle") for t in TASKS if t != "nogoal"}
    assert wanted | {("nogoal", "explorer"), ("nogoal", "random")} <= set(rows)
    threshold = f"{TaskMetricConfig().coverage_success:g}"
    assert f"coverage >= {threshold} with no collision" in section
    nogoal_page = (ROOT / "docs" / "tasks" / "nogoal.md").read_text()
    assert f"COVERAGE ≥ {threshold} (`TaskMetricConfig.coverage_success`)" in nogoal_page
