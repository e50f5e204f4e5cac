"""A nogoal episode ends at its budget whatever the agent does (docs/tasks/nogoal.md): the smaller of its
budget_steps and the actions budget_s allows at the control interval, in rollout, baseline and the gymnasium env
alike, as the budget's end (truncated, not a failure); evaluate's time and coverage are those of the budget."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
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


def _walk_past(row: dict, extra: list[list[float]], budget: int) -> dict:
    """An external agent's prediction for a nogoal episode: its first budget + 1 poses, then as many more as
    `extra` gives (twice the budget's poses in all), self-reported c(t), stopped at the end."""
    poses = row["poses"][: budget + 1] + extra
    c = row["collision_intensity"][: budget + 1] + [0.0] * len(extra)
    return {"episode_id": row["episode_id"], "poses": poses, "stopped": True, "collision_intensity": c}


def test_evaluate_scores_a_nogoal_prediction_only_up_to_its_budget(nogoal_run, run_cli, tmp_path):
    """Predictions made outside sagebench's simulator that run past a nogoal episode's budget (twice its poses,
    walking on over floor it has not covered) score the coverage and time of the budget's poses alone, and evaluate
    says how many episodes it cut; vln predictions (no budget) are scored whole, as before."""
    from sagebench.episodes.load import load_episodes
    from sagebench.metrics.exploration import score_exploration
    from sagebench.stages.evaluate import read_navigable_map

    budgets = _budgets(nogoal_run)
    for task, agent in (("nogoal", "random"), ("vln", "oracle")):
        code, _, err = run_cli("-q", "baseline", "--agent", agent, "--run", nogoal_run, "--task", task,
                               "--out", tmp_path / f"{task}.jsonl")
        assert code == 0, err
    nogoal = [json.loads(line) for line in (tmp_path / "nogoal.jsonl").read_text().splitlines()]
    vln = (tmp_path / "vln.jsonl").read_text()
    assert max(len(json.loads(line)["poses"]) for line in vln.splitlines()) > max(budgets.values()) + 1
    far = [[*p[:3], 0.0] for e in load_episodes(nogoal_run) if e.task == "vln" for p in e.reference_path.tolist()]
    files = {}
    for name, extra in (("within", 0), ("past", 1)):
        rows = [_walk_past(r, (far * 20)[: extra * budgets[r["episode_id"]]], budgets[r["episode_id"]])
                for r in nogoal]
        assert all(len(r["poses"]) == (1 + extra) * budgets[r["episode_id"]] + 1 for r in rows)
        files[name] = tmp_path / f"{name}.jsonl"
        files[name].write_text(vln + "".join(json.dumps(r) + "\n" for r in rows))
    navmap = read_navigable_map(nogoal_run, "tiny")
    whole = [score_exploration(np.asarray(r["poses"]), navmap.main_region, navmap.resolution, navmap.origin,
                               radius=navmap.snap_radius, min_coverage=0.1, step_seconds=0.5)
             for r in map(json.loads, files["past"].read_text().splitlines()[-len(nogoal):])]
    docs, said = {}, {}
    for name, path in files.items():
        code, said[name], err = run_cli("evaluate", "--run", nogoal_run, "--predictions", path,
                                        "--out", tmp_path / f"{name}.json")
        assert code == 0, err
        docs[name] = json.loads((tmp_path / f"{name}.json").read_text())
    rows = {n: {r["episode_id"]: r for r in d["per_episode"]} for n, d in docs.items()}
    for eid, budget in budgets.items():
        past, within = rows["past"][eid], rows["within"][eid]
        assert {**past, "cut_at_budget": 0} == {**within, "cut_at_budget": 0} and past["time"] == budget * 0.5
        assert (past["cut_at_budget"], within["cut_at_budget"]) == (True, False)
    assert max(w.coverage for w in whole) > max(r["coverage"] for r in rows["past"].values() if r["task"] == "nogoal")
    assert docs["past"]["by_task"] == docs["within"]["by_task"]
    assert {k: v for k, v in rows["past"].items() if k not in budgets} == \
        {k: v for k, v in rows["within"].items() if k not in budgets}
    assert "nogoal: 2 of 2 episodes ran past their budget and were scored up to it" in said["past"]
    assert "nogoal: 0 of 2 episodes ran past their budget" in said["within"]
    assert (docs["past"]["cut_at_budget"], docs["within"]["cut_at_budget"]) == (2, 0)
