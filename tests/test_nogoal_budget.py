"""A nogoal episode ends at its budget whatever the agent does (docs/tasks/nogoal.md): the smaller of its
budget_steps and the actions budget_s allows at the control interval, in rollout, baseline and the gymnasium env
alike, as the budget's end (truncated, not a failure); evaluate's time and coverage are those of the budget."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

BUDGET_S = 3.0  # --nogoal-budget: 6 actions of 0.5 s
STEPS_FIRST = 4  # budget_steps of the first nogoal episode, below what its budget_s allows


@pytest.fixture(scope="module")
def nogoal_run(tiny_run, tmp_path_factory) -> Path:
    """tiny_run with 2 nogoal episodes of a 3 s budget, the first also of a 4-step budget. Read-only: copy it."""
    from sagebench.cli import main

    run = tmp_path_factory.mktemp("nogoal") / "run"
    shutil.copytree(tiny_run, run)
    with pytest.raises(SystemExit) as done:
        main(["-q", "gen-trajectories", str(run), "--per-scene", "4", "--min-geodesic", "1", "--tasks", "vln,nogoal",
              "--task-episodes", "2", "--nogoal-budget", str(BUDGET_S)])
    assert done.value.code in (0, None)
    (shard,) = (run / "episodes" / "tiny").glob("part-*.parquet")
    table = pq.read_table(shard)
    steps = table.column("budget_steps").to_pylist()
    steps[table.column("task").to_pylist().index("nogoal")] = STEPS_FIRST
    i = table.schema.get_field_index("budget_steps")
    pq.write_table(table.set_column(i, table.schema.field(i), pa.array(steps, pa.int32())), shard)
    return run


def _budgets(run: Path, control_interval: float = 0.5) -> dict[str, int]:
    """nogoal episode id -> the actions the test expects it may take."""
    from sagebench.episodes.load import load_episodes

    rows = [e for e in load_episodes(run) if e.task == "nogoal"]
    assert [e.budget_steps for e in rows] == [STEPS_FIRST, 160]
    return {e.episode_id: min(e.budget_steps, int(BUDGET_S / control_interval)) for e in rows}


@pytest.mark.parametrize("control_interval", [0.5, 1.0])
def test_the_gym_env_truncates_a_nogoal_episode_at_its_budget(control_interval, nogoal_run):
    """An agent that turns in place forever (it never stops, never leaves the map) is cut at the episode's budget:
    budget_steps where smaller, else budget_s over the control interval."""
    from sagebench.env import NavEnv
    from sagebench.navsim.actions import Action
    from sagebench.settings.rollout import EnvConfig
    from sagebench.settings.shared import ActionConfig

    env = NavEnv(nogoal_run, EnvConfig(task="nogoal", observations=(), privileged=("pose",),
                                       actions=ActionConfig(control_interval=control_interval)))
    for eid, budget in _budgets(nogoal_run, control_interval).items():
        env.reset(options={"episode_id": eid})
        while True:
            _, _, terminated, truncated, info = env.step(Action.TURN_LEFT)
            if terminated or truncated:
                break
        assert (terminated, truncated, info["outcome"], info["steps"]) == (False, True, "budget", budget), eid
        assert len(env.prediction().poses) == budget + 1 and not env.prediction().stopped


def test_baseline_and_rollout_end_nogoal_episodes_at_their_budget_and_evaluate_scores_that(nogoal_run, run_cli,
                                                                                          tmp_path):
    """The random walk (10 to 150 actions before it stops) is cut at the budget, by baseline and rollout alike,
    none of its episodes failed; evaluate's TIME_S is the budget's, its coverage that of the budget's poses."""
    budgets = _budgets(nogoal_run)
    got = {}
    for command in (["baseline", "--agent", "random"], ["rollout", "--policy", "random", "--obs", "none"]):
        out = tmp_path / f"{command[0]}.jsonl"
        code, stdout, err = run_cli(*command, "--run", nogoal_run, "--task", "nogoal", "--out", out)
        assert code == 0, err
        assert "FAILED" not in stdout and "(0 stopped by the" in stdout, stdout
        got[command[0]] = out.read_bytes()
        rows = [json.loads(line) for line in got[command[0]].splitlines()]
        assert {r["episode_id"]: len(r["poses"]) - 1 for r in rows} == budgets
    assert got["baseline"] == got["rollout"]
    scored = tmp_path / "scores.json"
    code, _, err = run_cli("-q", "evaluate", "--run", nogoal_run, "--predictions", tmp_path / "baseline.jsonl",
                           "--out", scored)
    assert code == 0, err
    doc = json.loads(scored.read_text())
    times = {r["episode_id"]: r["time"] for r in doc["per_episode"]}
    assert times == {eid: steps * 0.5 for eid, steps in budgets.items()}
    assert doc["by_task"]["nogoal"]["time"] == pytest.approx(sum(budgets.values()) * 0.5 / len(budgets))
