"""`sagebench rollout` against policy servers that fail (tests/fake_policy.py): every finished episode is kept,
failed ones are recorded, --resume ends with the bytes of a clean rollout; subsets are recorded and scored
exactly; the continuous action space from the command line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fake_policy import FakePolicy

# a small depth image keeps the policy's decisions real and the renders cheap; 12 episodes of at most 6 requests
ARGS = ("--obs", "depth", "--width", "16", "--height", "12", "--episodes", "12", "--seed", "3")


@pytest.fixture
def server():
    made: list[FakePolicy] = []

    def start(*args, **kwargs) -> FakePolicy:
        made.append(FakePolicy(*args, **kwargs))
        return made[-1]

    yield start
    for s in made:
        s.close()


@pytest.fixture(scope="module")
def clean(demo_eval_run, tmp_path_factory) -> Path:
    """The predictions of an uninterrupted rollout against a server that never fails."""
    from sagebench.cli import main

    s = FakePolicy()
    out = tmp_path_factory.mktemp("clean") / "p.jsonl"
    try:
        with pytest.raises(SystemExit) as done:
            main(["rollout", "--run", str(demo_eval_run), "--out", str(out), "--policy", s.url, "--quiet", *ARGS])
    finally:
        s.close()
    assert done.value.code in (0, None)
    return out


def lines(path: Path) -> list[dict]:
    return [json.loads(t) for t in path.read_text().splitlines()]


def record(out: Path) -> dict:
    return json.loads(out.with_name(out.stem + "_rollout.json").read_text())


def test_a_500_on_request_41_fails_one_episode_keeps_the_rest_and_resume_completes_them(demo_eval_run, clean, server,
                                                                                        tmp_path, run_cli):
    out = tmp_path / "p.jsonl"
    bad = server("status500", faulty=lambda n: n == 41)
    code, stdout, _ = run_cli("rollout", "--run", demo_eval_run, "--out", out, "--policy", bad.url, *ARGS)
    rec = record(out)
    (failed,) = rec["failed_by_policy"]
    assert code == 1 and bad.requests > 41 and not rec["complete"]
    assert failed["reason"].endswith("HTTP 500 policy crashed") and f"FAILED by the policy: {failed['episode_id']}" in stdout
    kept = {row["episode_id"]: row for row in lines(out)}
    assert len(kept) == 11 and failed["episode_id"] not in kept
    assert all(kept[r["episode_id"]] == r for r in lines(clean) if r["episode_id"] in kept)  # as a clean run has them
    good = server()
    code, stdout, _ = run_cli("rollout", "--run", demo_eval_run, "--out", out, "--policy", good.url, "--resume")
    assert code == 0, stdout
    assert out.read_bytes() == clean.read_bytes() and len(good.seen) <= 6  # only the failed episode ran again
    assert record(out)["complete"] and record(out)["failed_by_policy"] == []
    assert record(out)["episodes"] == record(clean)["episodes"]


@pytest.mark.parametrize("fault", ["drip", "hang", "close"])
def test_a_server_that_drips_hangs_or_closes_fails_its_episodes_within_the_deadline(demo_eval_run, clean, server,
                                                                                   tmp_path, run_cli, fault):
    out = tmp_path / "p.jsonl"
    bad = server(fault, faulty=lambda n: n > 50)  # answers the first batch's 48 requests and 2 more, then fails
    code, stdout, _ = run_cli("rollout", "--run", demo_eval_run, "--out", out, "--policy", bad.url,
                              "--policy-timeout", "1", "--max-policy-failures", "1", *ARGS)
    rec = record(out)
    assert code == 1 and len(rec["failed_by_policy"]) >= 2 and "stopped: more than the allowed policy failures" in stdout
    why = {"drip": "no reply within 1 s", "hang": "no reply within 1 s", "close": "connection error: "}[fault]
    assert all(why in f["reason"] for f in rec["failed_by_policy"])
    kept = lines(out)
    assert len(kept) == 8 and all(r in lines(clean) for r in kept)  # the first batch, as a clean run has it
    with out.open("a") as f:  # and a kill inside a write: a torn last line
        f.write(out.read_text().splitlines()[0][:20])
    good = server()
    assert run_cli("rollout", "--run", demo_eval_run, "--out", out, "--policy", good.url, "--resume")[0] == 0
    assert out.read_bytes() == clean.read_bytes()


def test_a_closed_connection_is_retried_without_failing_anything(demo_eval_run, clean, server, tmp_path, run_cli):
    out = tmp_path / "p.jsonl"
    flaky = server("close", faulty=lambda n: n % 7 == 0)
    code, _, _ = run_cli("rollout", "--run", demo_eval_run, "--out", out, "--policy", flaky.url, *ARGS)
    assert code == 0 and out.read_bytes() == clean.read_bytes() and record(out)["failed_by_policy"] == []


def test_rollout_episodes_8_then_evaluate_scores_exactly_those_8(demo_eval_run, tmp_path, run_cli):
    out, res = tmp_path / "s.jsonl", tmp_path / "r.json"
    assert run_cli("rollout", "--run", demo_eval_run, "--out", out, "--policy", "straight", "--obs", "none",
                   "--episodes", "8")[0] == 0
    rows = lines(out)
    code, stdout, _ = run_cli("evaluate", "--run", demo_eval_run, "--predictions", out, "--out", res)
    data = json.loads(res.read_text())
    icp = np.mean([np.mean(r["collision_intensity"]) for r in rows])  # each episode's mean c(t), then the mean
    assert code == 0 and data["episodes"] == 8 == len(rows) and data["missing"] == []
    assert [e["episode_id"] for e in data["per_episode"]] == record(out)["episodes"] == [r["episode_id"] for r in rows]
    assert data["overall"]["icp"] == pytest.approx(icp, abs=1e-6)
    assert "scored exactly the 8 episodes the rollout was asked to run" in stdout
    assert "privileged: pose, episode" in stdout  # the straight baseline steers by the pose and reads the goal
    code, _, _ = run_cli("evaluate", "--run", demo_eval_run, "--predictions", out, "--out", res, "--all-episodes",
                         "--allow-missing")
    assert code == 0 and json.loads(res.read_text())["episodes"] == 24


def test_a_failed_episode_scores_as_missing(demo_eval_run, server, tmp_path, run_cli):
    out, res = tmp_path / "p.jsonl", tmp_path / "r.json"
    bad = server("status500", faulty=lambda n: n == 1)
    run_cli("rollout", "--run", demo_eval_run, "--out", out, "--policy", bad.url, "--workers", "1", *ARGS[:-4],
            "--episodes", "2")
    (failed,) = record(out)["failed_by_policy"]
    code, stdout, _ = run_cli("evaluate", "--run", demo_eval_run, "--predictions", out, "--out", res)
    data = json.loads(res.read_text())
    assert code == 0 and data["missing"] == [failed["episode_id"]] and data["episodes"] == 2
    assert f"1 episodes failed by the policy (scored as missing): {failed['episode_id']}" in stdout
    assert "the rollout is incomplete: sagebench rollout --resume runs the rest" in stdout


def test_split_and_episode_ids_pick_the_episodes_and_are_recorded(demo_eval_run, tmp_path, run_cli):
    from sagebench.episodes.load import load_episodes

    episodes = load_episodes(demo_eval_run, None)
    split = episodes[0].split
    in_split = [e.episode_id for e in episodes if e.split == split]
    out = tmp_path / "p.jsonl"
    assert run_cli("rollout", "--run", demo_eval_run, "--out", out, "--policy", "oracle", "--obs", "none", "--split",
                   split)[0] == 0
    assert record(out)["episodes"] == in_split == [r["episode_id"] for r in lines(out)]
    picked = [in_split[2], in_split[0]]
    assert run_cli("rollout", "--run", demo_eval_run, "--out", out, "--policy", "oracle", "--obs", "none",
                   *[a for i in picked for a in ("--episode-id", i)])[0] == 0
    assert record(out)["episodes"] == [in_split[0], in_split[2]]  # run order


@pytest.mark.parametrize("args, message", [
    (("--episode-id", "nope"), "error: --episode-id: no episode 'nope' in this run"),
    (("--split", "dev"), "error: --split: 'dev' is not a split (one of train, val_seen, val_unseen, test, trajectory_unseen, instruction_unseen)"),
    (("--resume",), "error: --resume: nothing to resume: no p_rollout.json beside "),
    (("--resume", "--profile", "vlnce"), "error: --profile: not with --resume: a resumed rollout keeps the settings"),
    (("--action-space", "continuous"), "error: --action-space: the built-in policy oracle acts in the discrete"),
    (("--profile", "vlnce", "--width", "64"), "error: --width: the vlnce profile's sizes are VLN-CE's"),
    (("--privileged", "compass"), "error: --privileged: 'compass' is not one of pose, gps_compass, instance"),
])
def test_bad_subsets_and_resumes_are_one_line_and_write_nothing(demo_eval_run, tmp_path, run_cli, args, message):
    code, _, err = run_cli("rollout", "--run", demo_eval_run, "--out", tmp_path / "p.jsonl", *args)
    assert code == 2 and err.startswith(message) and len(err.strip().splitlines()) == 1, err
    assert not list(tmp_path.iterdir())


def test_the_continuous_action_space_from_the_command_line(demo_eval_run, tmp_path, run_cli):
    s = FakePolicy(continuous=True)
    out = tmp_path / "p.jsonl"
    try:
        code, _, err = run_cli("rollout", "--run", demo_eval_run, "--out", out, "--policy", s.url, "--obs", "none",
                               "--action-space", "continuous", "--episodes", "2")
    finally:
        s.close()
    assert code == 0, err
    assert {f["action_space"] for f, _ in s.seen} == {"continuous"}
    for row in lines(out):  # v = 0.3 m/s for 0.5 s per action unless blocked, then stop
        steps = np.hypot(*np.diff(np.array(row["poses"])[:, :2], axis=0).T)
        assert row["stopped"] and len(steps) == 3
        assert all(d == pytest.approx(0.15, abs=1e-4) or c > 0 for d, c in zip(steps, row["collision_intensity"][1:]))


@pytest.mark.parametrize("was, new, expect", [
    ("sage+http://a:1/nogoal_step", "sage+http://b:2/nogoal_step", "sage+http://b:2/nogoal_step"),
    ("sage+socket://a:1", "sage+socket://b:2", "sage+socket://b:2"),
    ("http://a:1/act", "https://b:2/act", "https://b:2/act"),
    ("sage+http://a:1", "oracle", "sage+http://a:1"),  # --policy not given: the record's
    ("sage+http://a:1", "http://b:2", "error: --policy: the rollout being resumed ran SAGE's http client on "
                                      "/vln_step, not a policy server over sagebench's HTTP protocol"),
    ("sage+http://a:1", "sage+http://a:1/nogoal_step", "error: --policy: the rollout being resumed ran SAGE's http "
                                                       "client on /vln_step, not SAGE's http client on /nogoal_step"),
    ("http://a:1", "sage+socket://a:1", "error: --policy: the rollout being resumed ran a policy server over "
                                        "sagebench's HTTP protocol, not SAGE's socket client"),
    ("straight", "http://b:2", "error: --policy: the rollout being resumed ran the built-in policy straight, not a "
                               "policy server over sagebench's HTTP protocol"),
])
def test_a_resumed_rollout_takes_a_new_url_only_for_the_same_client(was, new, expect, tmp_path):
    """A policy server may move (a new host or port) between a killed rollout and its --resume; the client that
    decides the predictions may not change. A sage+ URL given with --resume was ignored: the rollout went on
    calling the old server."""
    from types import SimpleNamespace

    from sagebench.errors import ConfigError
    from sagebench.settings.rollout import RolloutConfig
    from sagebench.stages.rollout import resumed

    earlier = SimpleNamespace(policy=was, settings={})
    try:
        got = resumed(RolloutConfig(policy=new), earlier, tmp_path / "p.jsonl").policy
    except ConfigError as err:
        got = f"error: {err}"
    assert got == expect
