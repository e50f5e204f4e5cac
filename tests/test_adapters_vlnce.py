"""The VLN-CE adapter: an agent written as vlnce_baselines writes them (tests/vlnce_agents.py) runs unchanged
in-process and behind the policy protocol with identical predictions; the vlnce preset's settings and their
effect on scoring."""

from __future__ import annotations

import json
import re
import threading

import numpy as np
import pytest

from vlnce_agents import HabitatSimActions

from sagebench.adapters.vlnce import serve, vlnce_action, vlnce_observations
from sagebench.navsim.actions import Action
from sagebench.navsim.http_policy import RequestFailed, post
from sagebench.navsim.protocol import encode_request, request_fields

VLNCE_RUN = ("--preset", "vlnce", "--episodes", "3", "--seed", "1")


@pytest.fixture
def agent_server():
    servers = []

    def start(agent):
        server = serve(agent)
        thread = threading.Thread(target=server.serve_forever, daemon=True)
        thread.start()
        servers.append((server, thread))
        return f"http://127.0.0.1:{server.server_address[1]}/act"

    start.servers = servers
    yield start
    for server, thread in servers:
        server.shutdown()
        server.server_close()
        thread.join(timeout=10)


def test_an_agent_runs_unchanged_in_process_and_over_http_with_identical_results(tiny_run, tmp_path, run_cli,
                                                                               agent_server):
    import vlnce_agents

    inproc, http, one = tmp_path / "in.jsonl", tmp_path / "http.jsonl", tmp_path / "one.jsonl"
    code, stdout, err = run_cli("rollout", "--run", tiny_run, "--out", inproc, "--policy",
                                "vlnce:vlnce_agents:DepthAgent", *VLNCE_RUN)
    assert code == 0, err
    assert stdout.startswith("preset: success distance 3 m (default: each episode's goal_radius); camera height 1.25 m "
                             "(default 1.2); observations: the vlnce profile (default custom); instruction tokens: the "
                             "habitat tokenizer (default sagebench); agent body: the run's maps', radius 0.2 m, height "
                             "1.2 m, not VLN-CE's radius 0.1 m, height 1.5 m (build-scene --agent-radius 0.1 "
                             "--band-max 1.5 builds a run for it)\n")
    code, _, err = run_cli("rollout", "--run", tiny_run, "--out", http, "--policy",
                           agent_server(vlnce_agents.DepthAgent), *VLNCE_RUN)
    assert code == 0, err
    assert http.read_bytes() == inproc.read_bytes()
    rows = [json.loads(t) for t in inproc.read_text().splitlines()]
    assert len(rows) == 3 and all(r["stopped"] for r in rows) and max(len(r["poses"]) for r in rows) >= 5
    moved = [np.hypot(*np.diff(np.array(r["poses"])[:, :2], axis=0).T).sum() for r in rows]
    assert max(moved) > 0.5  # it walked, not only turned
    assert run_cli("rollout", "--run", tiny_run, "--out", one, "--policy", "vlnce:vlnce_agents:ONE_AGENT",
                   *VLNCE_RUN)[0] == 0
    assert one.read_bytes() == inproc.read_bytes()  # one object, one episode at a time: the same
    # what the agent saw: VLN-CE's shapes and dtypes
    assert set(vlnce_agents.ONE_AGENT.checked) == {((224, 224, 3), np.dtype(np.uint8), (256, 256, 1), np.dtype(np.float32), 200)}



def test_an_imagenav_agent_sees_the_same_goal_image_in_process_and_behind_serve(tiny_goal_tasks_run, tmp_path, run_cli,
                                                                              agent_server):
    """habitat's `imagegoal`, [224, 224, 3] uint8, reaches the agent in place of the instruction, byte for byte the
    same in-process and through the policy protocol in each encoding."""
    import vlnce_agents

    seen = {}
    for how, policy, encoding in [("in-process", "vlnce:vlnce_agents:GoalAgent", "raw"),
                                  *((e, agent_server(vlnce_agents.GoalAgent), e) for e in ("raw", "png", "json"))]:
        vlnce_agents.GoalAgent.seen = []
        code, stdout, err = run_cli("rollout", "--run", tiny_goal_tasks_run, "--out", tmp_path / "p.jsonl",
                                    "--policy", policy, "--preset", "vlnce", "--task", "imagenav",
                                    "--policy-encoding", encoding)
        assert code == 0 and "FAILED" not in stdout, (how, err, stdout)
        seen[how] = sorted(g.tobytes() for g in vlnce_agents.GoalAgent.seen)
        assert {(g.shape, g.dtype) for g in vlnce_agents.GoalAgent.seen} == {((224, 224, 3), np.dtype(np.uint8))}
    assert len(seen["in-process"]) == 2 and len(set(seen["in-process"])) == 2
    assert seen["raw"] == seen["png"] == seen["json"] == seen["in-process"]

class _FirstStepAgent:
    """Turns left on its episode's first step and moves forward after: each answer tells whether the server kept
    the episode's agent or made it anew."""

    def reset(self):
        self.steps = 0

    def act(self, observations):
        self.steps += 1
        return {"action": HabitatSimActions.TURN_LEFT if self.steps == 1 else HabitatSimActions.MOVE_FORWARD}


def test_a_full_agent_table_lets_the_least_recently_asked_agent_go_never_the_new_one(agent_server, monkeypatch):
    """Episodes cut by the step limit never say STOP, so a long rollout fills the server's table (LIVE_EPISODES,
    made 3 here): a new episode then evicts the agent asked least recently; the new one, and one still
    stepping, keep theirs; the evicted one is refused, never restarted from nothing mid-way."""
    import sagebench.adapters.vlnce as vlnce

    monkeypatch.setattr(vlnce, "LIVE_EPISODES", 3)
    url = agent_server(_FirstStepAgent)

    def ask(episode: str, step: int) -> str:
        return Action(json.loads(post(url, *_request(episode, step), timeout=30.0))["action"]).name

    first, kept = "TURN_LEFT", "MOVE_FORWARD"
    assert [ask("a", 0), ask("b", 0), ask("c", 0), ask("a", 1)] == [first, first, first, kept]
    assert [ask("d", 0), ask("d", 1)] == [first, kept]  # b, asked least recently, made room for d
    assert [ask("a", 2), ask("c", 1)] == [kept, kept]
    with pytest.raises(RequestFailed, match=f"^HTTP 409 Conflict: episode {'b' * 16} is not running on this server "):
        ask("b", 1)


_OBS = {"rgb": np.zeros((2, 2, 3), np.uint8), "depth": np.zeros((2, 2, 1), np.float32), "instruction": "go",
        "instruction_tokens": np.array([5, 0], np.int64)}


def _request(episode: str, step: int) -> tuple[bytes, str]:
    """(body, Content-Type) of step `step` of episode `episode` * 16, as HttpPolicy sends it."""
    fields = request_fields(_OBS, episode_id=episode * 16, step=step, action_space="discrete", profile="vlnce")
    content_type, body = encode_request(_OBS, fields)
    return body, content_type


def test_the_agent_gets_vlnces_observation_keys():
    obs = {"rgb": np.zeros((224, 224, 3), np.uint8), "depth": np.zeros((256, 256, 1), np.float32),
           "instruction": "go", "instruction_tokens": np.array([5, 0], np.int64), "gps": np.zeros(2, np.float32)}
    seen = vlnce_observations(obs, 42)
    assert set(seen) == {"rgb", "depth", "instruction", "gps"}
    assert seen["instruction"] == {"text": "go", "tokens": [5, 0], "trajectory_id": 42}
    with pytest.raises(ValueError, match="needs the vlnce profile's observations .*; instruction_tokens is missing"):
        vlnce_observations({k: v for k, v in obs.items() if k != "instruction_tokens"}, 1)


@pytest.mark.parametrize("reply, expected", [
    ({"action": 0}, Action.STOP), ({"action": np.int64(1)}, Action.MOVE_FORWARD), (2, Action.TURN_LEFT),
    ("TURN_RIGHT", Action.TURN_RIGHT), ({"action": {"action": "STOP"}}, Action.STOP),
])
def test_habitat_style_actions_are_vlnces_ids(reply, expected):
    assert vlnce_action(reply) == expected


@pytest.mark.parametrize("reply", [{"action": 4}, {"action": True}, {"action": "JUMP"}, None])
def test_anything_else_is_refused(reply):
    with pytest.raises(ValueError, match="is not one of VLN-CE's 0 STOP, 1 MOVE_FORWARD, 2 TURN_LEFT, 3 TURN_RIGHT"):
        vlnce_action(reply)


def test_a_vlnce_agent_without_the_vlnce_profile_is_refused(tiny_run, tmp_path, run_cli):
    code, _, err = run_cli("rollout", "--run", tiny_run, "--out", tmp_path / "p.jsonl", "--policy",
                           "vlnce:vlnce_agents:DepthAgent")
    assert code == 2 and err == ("error: --profile: a VLN-CE agent needs the vlnce profile and discrete actions "
                                 "(--preset vlnce)\n")
    code, _, err = run_cli("rollout", "--run", tiny_run, "--out", tmp_path / "p.jsonl", "--policy",
                           "vlnce:vlnce_agents:Nobody", "--preset", "vlnce")
    assert code == 2 and err.startswith("error: --policy: cannot run 'vlnce:vlnce_agents:Nobody': ")
    assert not list(tmp_path.iterdir())


def test_the_preset_scores_success_within_3_m(tiny_run, tmp_path, run_cli):
    out, res = tmp_path / "s.jsonl", tmp_path / "r.json"
    assert run_cli("rollout", "--run", tiny_run, "--out", out, "--policy", "straight", "--preset", "vlnce",
                   "--obs", "none")[0] == 2  # the vlnce profile renders its own images
    assert run_cli("rollout", "--run", tiny_run, "--out", out, "--policy", "straight", "--preset", "vlnce",
                   "--episodes", "6", "--max-steps", "40")[0] == 0
    code, stdout, _ = run_cli("evaluate", "--run", tiny_run, "--predictions", out, "--out", res)
    data = json.loads(res.read_text())
    stopped = {json.loads(t)["episode_id"]: json.loads(t)["stopped"] for t in out.read_text().splitlines()}
    assert code == 0 and data["rollout"]["success_distance"] == 3.0 and "success within 3 m" in stdout
    for e in data["per_episode"]:
        assert e["sr"] == float(stopped[e["episode_id"]] and e["ne"] <= 3.0)
    assert any(e["sr"] == 1.0 and e["ne"] > 1.0 for e in data["per_episode"])  # a success at 1 m would fail it


class _Recorded(_FirstStepAgent):
    """_FirstStepAgent, each one kept: its `steps` counts the act() calls it got."""

    made: list = []

    def __init__(self):
        _Recorded.made.append(self)


def test_a_repeated_step_gets_its_first_answer_and_the_agent_acts_once(agent_server):
    """A retried request (its reply was lost) carries the same episode and step: the server answers it from the
    episode's reply cache, not by acting again (an agent acting twice walks a different episode)."""
    _Recorded.made = []
    url = agent_server(_Recorded)
    answers = [post(url, *_request("a", step), timeout=30.0) for step in (0, 1, 1)]
    assert answers[1] == answers[2] and [a.steps for a in _Recorded.made] == [2]
    with pytest.raises(RequestFailed, match=f"^HTTP 409 Conflict: episode {'a' * 16}: step 3 after step 1$"):
        post(url, *_request("a", 3), timeout=30.0)


def _drop_reply(server, number: int) -> None:
    """Make `server` (serve's) act on its `number`-th request but close the connection instead of replying, as a
    reply lost on the way does: the client retries the request."""
    import io
    import itertools

    count = itertools.count(1)

    class Dropping(server.RequestHandlerClass):
        def do_POST(self):  # noqa: N802 - http.server's name
            if next(count) == number:
                self.wfile, self.close_connection = io.BytesIO(), True
            super().do_POST()

    server.RequestHandlerClass = Dropping


def test_a_lost_reply_changes_nothing(tiny_run, tmp_path, run_cli, agent_server):
    import vlnce_agents

    inproc, http = tmp_path / "in.jsonl", tmp_path / "http.jsonl"
    assert run_cli("rollout", "--run", tiny_run, "--out", inproc, "--policy", "vlnce:vlnce_agents:DepthAgent",
                   *VLNCE_RUN)[0] == 0
    url = agent_server(vlnce_agents.DepthAgent)
    _drop_reply(next(s for s, _ in agent_server.servers), 5)  # episode 2 of the batch, step 1
    code, _, err = run_cli("rollout", "--run", tiny_run, "--out", http, "--policy", url, *VLNCE_RUN)
    assert code == 0, err
    assert http.read_bytes() == inproc.read_bytes()


class _FailsOnce:
    """Raises at its third step, the first episode only: asked again, it would walk on as if nothing happened."""

    raised = False

    def reset(self):
        self.steps = 0

    def act(self, observations):
        self.steps += 1
        if self.steps == 3 and not _FailsOnce.raised:
            _FailsOnce.raised = True
            raise RuntimeError("out of memory")
        return {"action": HabitatSimActions.STOP if self.steps > 6 else HabitatSimActions.MOVE_FORWARD}


def _failed_lines(stdout: str) -> list[str]:
    return [line for line in stdout.splitlines() if line.startswith("  FAILED by the policy: ")]


@pytest.mark.parametrize("over_http", [False, True])
def test_an_agent_that_raises_fails_its_episode_visibly(tiny_run, tmp_path, run_cli, agent_server, monkeypatch,
                                                       over_http):
    import vlnce_agents

    _FailsOnce.raised = False
    monkeypatch.setattr(vlnce_agents, "FailsOnce", _FailsOnce, raising=False)
    policy = agent_server(_FailsOnce) if over_http else "vlnce:vlnce_agents:FailsOnce"
    out = tmp_path / "p.jsonl"
    code, stdout, _ = run_cli("rollout", "--run", tiny_run, "--out", out, "--policy", policy, *VLNCE_RUN)
    assert code == 1  # an episode is left to run, not a complete-looking rollout
    [line] = _failed_lines(stdout)
    where = f"policy {policy} (step 2): HTTP 500 Internal Server Error: " if over_http else ""
    assert re.fullmatch(rf"  FAILED by the policy: \S+: {re.escape(where)}the agent raised RuntimeError: out of "
                        rf"memory \(at .*test_adapters_vlnce\.py:\d+\)" + (r" \(episode [0-9a-f]{16}, step 2\)"
                                                                         if over_http else ""), line), line
    assert len(out.read_text().splitlines()) == 2


def test_one_agent_object_behind_a_server_refuses_a_second_episode_at_once(tiny_run, tmp_path, run_cli,
                                                                          agent_server):
    """--batch 2 against a server holding one agent object: the agent is reset for the episode started second, so
    the other one's next request is refused (it fails, visibly); the one started second runs as alone."""
    import vlnce_agents

    alone, both = tmp_path / "alone.jsonl", tmp_path / "both.jsonl"
    args = ("--preset", "vlnce", "--episodes", "2", "--seed", "1")
    assert run_cli("rollout", "--run", tiny_run, "--out", alone, "--policy", "vlnce:vlnce_agents:DepthAgent",
                   *args)[0] == 0
    code, stdout, _ = run_cli("rollout", "--run", tiny_run, "--out", both, "--policy",
                              agent_server(vlnce_agents.DepthAgent()), "--batch", "2", *args)
    assert code == 1
    [line] = _failed_lines(stdout)
    assert re.search(r"HTTP 409 Conflict: episode [0-9a-f]{16}: a single agent object runs one episode at a time "
                     r"and episode [0-9a-f]{16} started after it \(run the rollout with --batch 1, or serve the "
                     r"agent's class\)$", line), line
    [kept] = both.read_text().splitlines()
    assert kept in alone.read_text().splitlines()


def _nested(depth: int) -> dict:
    reply: dict = {"action": 1}
    for _ in range(depth):
        reply = {"action": reply}
    return reply


class _Nested:
    """Answers an action wrapped 200,000 deep."""

    def reset(self):
        pass

    def act(self, observations):
        return _nested(200_000)


def test_an_answer_nested_200k_deep_fails_its_episode_not_the_rollout(tiny_run, tmp_path, run_cli, monkeypatch):
    import vlnce_agents

    monkeypatch.setattr(vlnce_agents, "Nested", _Nested, raising=False)
    code, stdout, _ = run_cli("rollout", "--run", tiny_run, "--out", tmp_path / "p.jsonl", "--policy",
                              "vlnce:vlnce_agents:Nested", "--preset", "vlnce", "--episodes", "1")
    assert code == 1
    [line] = _failed_lines(stdout)
    assert line.endswith(": the agent's action {'action': {'action': {'action': {...}}}} is not one of VLN-CE's "
                         "0 STOP, 1 MOVE_FORWARD, 2 TURN_LEFT, 3 TURN_RIGHT")


def test_a_request_past_the_servers_bounds_is_refused_with_why(agent_server):
    """Nesting a request's JSON 100,000 deep, or announcing a body over MAX_REQUEST_BYTES, gets an error reply
    (the server neither dies in the request's thread nor reads the body)."""
    import http.client
    import urllib.parse

    from sagebench.adapters.vlnce import MAX_REQUEST_BYTES

    url = agent_server(_FirstStepAgent)
    deep = b'{"a": ' * 100_000 + b"1" + b"}" * 100_000
    with pytest.raises(RequestFailed, match="^HTTP 400 Bad Request: TooDeep: .* nested deeper than 64 levels$"):
        post(url, deep, "application/json", timeout=30.0)
    where = urllib.parse.urlsplit(url)
    conn = http.client.HTTPConnection(where.hostname, where.port, timeout=30)
    conn.putrequest("POST", where.path)
    conn.putheader("Content-Type", "application/json")
    conn.putheader("Content-Length", str(MAX_REQUEST_BYTES + 1))
    conn.endheaders()
    reply = conn.getresponse()
    assert reply.status == 413 and json.loads(reply.read()) == {
        "error": f"a request's body must have a Content-Length of at most {MAX_REQUEST_BYTES:,} bytes"}
    conn.close()


def test_pointnav_and_objectnav_agents_get_habitats_goal_sensors_in_process_and_behind_serve(tiny_goal_tasks_run,
                                                                                           tmp_path, run_cli,
                                                                                           agent_server):
    """A VLN-CE agent on pointnav gets habitat's pointgoal_with_gps_compass ([2] float32 [rho, phi], at the start
    the episode's goal_polar), on objectnav habitat's objectgoal ([1] int64, the category's id in the agent's
    category_to_task_category_id), never an instruction; the same in-process and behind serve()."""
    import vlnce_agents
    from sagebench.episodes.load import load_episodes

    agent = vlnce_agents.SensorAgent
    episodes = load_episodes(tiny_goal_tasks_run)
    polar = sorted(tuple(e.goal_polar) for e in episodes if e.task == "pointnav")
    ids = sorted((agent.category_to_task_category_id[e.goal_category],) for e in episodes if e.task == "objectnav")
    assert len(polar) == len(ids) == 2
    got = {}
    for how, policy, encoding in [("in-process", "vlnce:vlnce_agents:SensorAgent", "raw"),
                                  *((e, agent_server(agent), e) for e in ("raw", "json"))]:
        for task, key, dtype, expect in (("pointnav", "pointgoal_with_gps_compass", np.float32, polar),
                                         ("objectnav", "objectgoal", np.int64, ids)):
            agent.seen = []
            code, stdout, err = run_cli("rollout", "--run", tiny_goal_tasks_run, "--out", tmp_path / "p.jsonl",
                                        "--policy", policy, "--preset", "vlnce", "--task", task,
                                        "--policy-encoding", encoding)
            assert code == 0 and "FAILED" not in stdout, (how, task, err, stdout)
            assert all(set(o) == {key} for o in agent.seen), (how, task, agent.seen)
            assert {(o[key].shape, o[key].dtype) for o in agent.seen} == {((2,) if key != "objectgoal" else (1,),
                                                                           np.dtype(dtype))}
            got[how, task] = sorted(tuple(o[key].tolist()) for o in agent.seen)
            assert np.allclose(got[how, task], expect, atol=1e-5), (how, task)
    assert got["raw", "pointnav"] == got["json", "pointnav"] == got["in-process", "pointnav"]
    assert got["raw", "objectnav"] == got["json", "objectnav"] == got["in-process", "objectnav"]


def test_an_objectnav_agent_without_habitats_category_map_fails_its_episodes_saying_why(tiny_goal_tasks_run, tmp_path,
                                                                                       run_cli):
    """An agent that knows no category ids cannot be told an ObjectNav goal: each episode fails by the policy, saying
    why (never a made-up id)."""
    code, stdout, _ = run_cli("rollout", "--run", tiny_goal_tasks_run, "--out", tmp_path / "p.jsonl", "--policy",
                              "vlnce:vlnce_agents:MaplessAgent", "--preset", "vlnce", "--task", "objectnav")
    assert code == 1 and stdout.count("category_to_task_category_id, and the agent (or its class) has none") == 2
