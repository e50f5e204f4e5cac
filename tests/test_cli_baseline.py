"""`sagebench baseline` (rollout's loop, no images) on a small demo run: three agents, three different and sensible
score profiles."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

SCENE = "demo_apartment_0"


@pytest.fixture(scope="module")
def baselines(demo_eval_run, tmp_path_factory, run_cli) -> dict[str, Path]:
    """Predictions of every baseline on demo_eval_run."""
    n = _episodes(demo_eval_run)
    out = tmp_path_factory.mktemp("baselines")
    paths = {}
    for agent in ("oracle", "straight", "random"):
        paths[agent] = out / f"{agent}.jsonl"
        code, stdout, err = run_cli("baseline", "--agent", agent, "--run", demo_eval_run, "--out", paths[agent])
        assert code == 0, err
        assert stdout.startswith(f"baseline {agent}: {n} episodes (")
    return paths


@pytest.fixture(scope="module")
def run_cli(request):
    """conftest's run_cli for module-scoped fixtures too (capsys is per test): (exit code, stdout, stderr)."""
    import contextlib
    import io

    from sagebench.cli import main
    from sagebench.ui import SETTINGS

    def run(*args):
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), pytest.raises(SystemExit) as exc:
            main([str(a) for a in args])
        SETTINGS.quiet = SETTINGS.debug = False
        return int(exc.value.code or 0), out.getvalue(), err.getvalue()

    return run


def _episodes(run_dir: Path) -> int:
    from sagebench.episodes.load import load_episodes

    return len(load_episodes(run_dir))


def _overall(run_dir: Path, predictions: Path) -> dict[str, float]:
    from sagebench.stages.evaluate import evaluate

    return evaluate(run_dir, predictions).summary.overall


def test_the_three_baselines_score_as_expected(demo_eval_run, baselines):
    oracle, straight, rand = (_overall(demo_eval_run, baselines[a]) for a in ("oracle", "straight", "random"))
    # measured: the oracle's 15-degree headings and 0.25 m moves leave the reference by centimetres, and pass
    # within the 0.01 m contact distance of a collider on a few steps (SPL 0.9914, nDTW 0.9826, ICP 0.0016; SPL
    # was 0.9927 before the demo's office chairs stood on casters: a changed scene, other trajectories)
    assert oracle["sr"] == 1.0 and oracle["csr"] == 1.0 and 0.0 < oracle["icp"] < 0.01
    assert oracle["spl"] == pytest.approx(0.9914, abs=1e-3) and oracle["ndtw"] == pytest.approx(0.9826, abs=1e-3)
    assert oracle["ne"] < 0.1
    # straight knows where the goal is but not the walls: fails some, bumps, cuts corners
    assert 0.0 < straight["sr"] < 1.0 and straight["icp"] > 0.05 and straight["ndtw"] < oracle["ndtw"]  # ICP 0.099
    # random wanders: rarely succeeds, least like the reference
    assert rand["sr"] < straight["sr"] and rand["ndtw"] < straight["ndtw"] and rand["csr"] < oracle["csr"]
    assert rand["ps"] < oracle["ps"]


def test_predictions_are_valid_and_deterministic(demo_eval_run, baselines, tmp_path, run_cli):
    from sagebench.evaluation.predictions import read_predictions

    rows = read_predictions(baselines["random"])
    assert len(rows) == _episodes(demo_eval_run) and all(p.collision_intensity is not None for _, p in rows)
    again = tmp_path / "again.jsonl"
    assert run_cli("baseline", "--agent", "random", "--run", demo_eval_run, "--out", again)[0] == 0
    assert again.read_bytes() == baselines["random"].read_bytes()
    other_seed = tmp_path / "seed1.jsonl"
    assert run_cli("baseline", "--agent", "random", "--run", demo_eval_run, "--out", other_seed, "--seed", "1")[0] == 0
    assert other_seed.read_bytes() != baselines["random"].read_bytes()
    one_scene = tmp_path / "scene.jsonl"
    assert run_cli("baseline", "--agent", "oracle", "--run", demo_eval_run, "--scene", SCENE, "--out", one_scene)[0] == 0
    assert one_scene.read_bytes() == baselines["oracle"].read_bytes()
    first = json.loads(baselines["oracle"].read_text().splitlines()[0])
    assert sorted(first) == ["collision_intensity", "episode_id", "intensity_source", "poses", "stopped"]
    assert first["intensity_source"] == "simulator"


def test_max_actions_ends_episodes_unstopped(demo_eval_run, tmp_path, run_cli):
    out = tmp_path / "short.jsonl"
    code, stdout, _ = run_cli("baseline", "--agent", "oracle", "--run", demo_eval_run, "--out", out, "--max-actions", "3")
    assert code == 0 and f"(0 stopped by the agent, {3 * _episodes(demo_eval_run)} actions)" in stdout
    assert _overall(demo_eval_run, out)["sr"] == 0.0


@pytest.mark.parametrize("args, message", [
    (["--agent", "walker"], "error: --agent: Input should be 'oracle', 'straight', 'random', 'stationary' or 'explorer'"),
    (["--agent", "oracle", "--max-actions", "0"], "error: --max-actions: Input should be greater than or equal to 1"),
    (["--agent", "oracle", "--scene", "nope"], "no episodes/nope/part-*.parquet (scenes found: demo_apartment_0); "
                                               "run `sagebench gen-trajectories` on this run first"),
])
def test_bad_options_are_exit_2_and_write_nothing(demo_eval_run, tmp_path, run_cli, args, message):
    out = tmp_path / "p.jsonl"
    code, _, err = run_cli("baseline", "--run", demo_eval_run, "--out", out, *args)
    assert code == 2 and message in err and not out.exists()


def test_a_run_without_scene_xml_is_exit_2(demo_built_run, tmp_path, run_cli):
    import shutil

    from sagebench.stages.gen_trajectories import GenTrajectoriesConfig, gen_trajectories

    run = tmp_path / "run"
    shutil.copytree(demo_built_run / "scenes", run / "scenes")
    gen_trajectories(run, GenTrajectoriesConfig(per_scene=2, seed=0))
    out = tmp_path / "p.jsonl"
    code, _, err = run_cli("baseline", "--agent", "oracle", "--run", run, "--out", out)
    assert code == 2 and not out.exists()
    assert err.strip() == f"error: {run / 'scenes' / SCENE / 'scene.xml'}: missing; run `sagebench export-usd` on this run first"
