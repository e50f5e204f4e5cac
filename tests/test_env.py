"""The closed-loop environment on the demo run: gymnasium's checker, the baselines through it, a real HTTP policy
server, vectorised == sequential, and rollout / evaluate on its predictions."""

from __future__ import annotations

import json
import re
import threading
import warnings
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from sagebench.env import ENV_ID, NavEnv, VectorNavEnv
from sagebench.metrics.episode import path_smoothness
from sagebench.navsim.actions import Action
from sagebench.navsim.protocol import decode_request
from sagebench.navsim.policies import RandomWalk, built_in
from sagebench.navsim.rollout import rollout
from sagebench.navsim.simulator import Simulator
from sagebench.errors import first_error
from sagebench.settings.rollout import EnvConfig
from sagebench.settings.shared import ActionConfig, ReplayConfig

BLIND = EnvConfig(observations=(), privileged=("pose",))  # the built-in baselines steer by the pose


# gymnasium's checker warns of any infinite Box limit: positions are scene metres and depth has no far plane
UNBOUNDED = {"A Box observation space maximum value is infinity. This is probably too high.",
             "A Box observation space minimum value is -infinity. This is probably too low."}


@pytest.mark.parametrize("replay, actions, problem", [
    (ReplayConfig(max_speed=0.3), ActionConfig(), "actions.forward_step / actions.control_interval "
     "(0.25 m / 0.5 s = 0.5 m/s) exceeds replay.max_speed (0.3 m/s)"),
    (ReplayConfig(max_turn_rate=0.5), ActionConfig(), "actions.turn_deg / actions.control_interval "
     "(15 deg / 0.5 s = 0.5236 rad/s) exceeds replay.max_turn_rate (0.5 rad/s)"),
    (ReplayConfig(), ActionConfig(forward_step=0.25, control_interval=0.25), "actions.forward_step / "
     "actions.control_interval (0.25 m / 0.25 s = 1 m/s) exceeds replay.max_speed (0.8 m/s)"),
])
def test_actions_beyond_the_envs_own_replay_limits_are_refused_naming_the_fields(replay, actions, problem):
    """A discrete action must be one the env's replay can drive (and stop against a wall): checked against the
    env's ReplayConfig, not a default one."""
    with pytest.raises(ValueError) as err:
        EnvConfig(replay=replay, actions=actions)
    assert first_error(err.value)[1] == problem
    # faster actions are fine where the env's replay allows them
    fast = EnvConfig(replay=ReplayConfig(max_speed=2.5), actions=ActionConfig(forward_step=1.0))
    assert fast.actions.forward_step / fast.actions.control_interval == 2.0


def test_gymnasium_makes_and_accepts_the_env(tiny_run):
    made = gymnasium.make("sagebench.env:sagebench/Nav-v0", run_dir=str(tiny_run),
                          config={"width": 32, "height": 24, "max_steps": 5, "privileged": ["pose", "instance"]})
    env = made.unwrapped
    assert isinstance(env, NavEnv) and made.spec.id == ENV_ID and env.metadata["render_fps"] == 2.0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env, skip_render_check=False)  # with a spec it also remakes the env for each render mode
    assert {re.sub(r"\x1b\[\d+m|WARN: ", "", str(w.message)) for w in caught} <= UNBOUNDED
    obs, info = env.reset(seed=3)
    assert obs["rgb"].shape == (24, 32, 3) and obs["rgb"].dtype == np.uint8
    assert obs["depth"].dtype == np.float32 and obs["instance"].dtype == np.int32
    assert obs["instruction"] and obs["pose"].shape == (4,) and info["outcome"] == "running"
    eid = info["episode_id"]
    assert env.reset(options={"episode_id": eid})[1]["episode_id"] == eid


def test_episodes_end_on_stop_and_on_the_step_limit(demo_eval_run):
    env = NavEnv(demo_eval_run, BLIND.model_copy(update={"max_steps": 3}))
    env.reset(seed=0)
    for k in range(3):
        _, _, terminated, truncated, info = env.step(Action.TURN_LEFT)
    assert (terminated, truncated, info["outcome"], info["steps"]) == (False, True, "step_limit", 3)
    with pytest.raises(RuntimeError, match="has ended"):
        env.step(Action.TURN_LEFT)
    env.reset(seed=0)
    _, _, terminated, truncated, info = env.step(Action.STOP)
    assert (terminated, truncated, info["outcome"], info["steps"]) == (True, False, "stop", 0)
    assert len(env.prediction().poses) == 1 and env.prediction().stopped


def test_the_oracle_reaches_every_goal(demo_eval_run):
    sim = Simulator(demo_eval_run, BLIND)
    result = rollout(sim, built_in("oracle"), sim.order, batch=len(sim.order))
    assert len(result.predictions) == len(sim.order) == len(sim.slots) > 0
    assert all(s.success == 1.0 for s in sim.slots)  # SR 1
    icp = [float(np.mean(p.collision_intensity)) for p in result.predictions]
    assert all(p.stopped for p in result.predictions) and max(icp) < 0.05
    assert np.mean(icp) < 0.01  # measured 0.0016: the 15-degree turns take it within 1 cm of a collider now and then


def test_straight_scrapes_walls_and_the_simulator_measures_it(demo_eval_run):
    sim = Simulator(demo_eval_run, BLIND)
    result = rollout(sim, built_in("straight"), sim.order, batch=len(sim.order))
    icp = np.array([np.mean(p.collision_intensity) for p in result.predictions])
    sr = np.array([s.success for s in sim.slots])
    assert 0.0 < sr.mean() < 1.0
    assert (icp > 0).mean() >= 0.25  # a quarter of its episodes pushed into colliders (measured, not replayed)
    # measured 0.531 and 0.099 (0.359 and 0.066 from the motion shortfall alone, without contact along the step):
    # it stops after 4 forward moves without progress, so its steps in the open dilute the mean
    assert icp.max() > 0.45 and icp.mean() > 0.08
    assert all(p.intensity_source == "simulator" for p in result.predictions)


def test_a_policy_that_only_turns_scores_the_smoothness_of_15_degree_turns(demo_eval_run):
    env = NavEnv(demo_eval_run, BLIND.model_copy(update={"max_steps": 12}))
    env.reset(seed=1)
    for _ in range(12):
        env.step(Action.TURN_RIGHT)
    yaw = np.array(env.prediction().poses)[:, 3]
    assert np.allclose(np.diff(np.unwrap(yaw)), -np.radians(15), atol=1e-6)
    assert path_smoothness(yaw) == pytest.approx(1 - 15 / 180, abs=1e-6)  # PS penalises the turn per step


def test_vectorised_equals_sequential_byte_for_byte(tiny_run):
    cfg = EnvConfig(width=32, height=24, observations=("rgb", "depth"), max_steps=25)
    ids = Simulator(tiny_run, cfg).order[:4]
    together = rollout(Simulator(tiny_run, cfg, threads=2), RandomWalk(seed=5), ids, batch=4, sheet=4)
    alone = rollout(Simulator(tiny_run, cfg), RandomWalk(seed=5), ids, batch=1, sheet=4)
    assert [p.model_dump_json() for p in together.predictions] == [p.model_dump_json() for p in alone.predictions]
    for a, b in zip(together.views, alone.views):
        assert [f.tobytes() for f in a.frames + [a.last]] == [f.tobytes() for f in b.frames + [b.last]]
    assert together.steps == alone.steps > 4
    vec = VectorNavEnv(tiny_run, cfg)
    obs, _ = vec.reset(ids[:2])
    results = vec.step([Action.MOVE_FORWARD, Action.TURN_LEFT])
    single = NavEnv(tiny_run, cfg)
    single.reset(options={"episode_id": ids[1]})
    o, *_ = single.step(Action.TURN_LEFT)
    assert results[1].observation["rgb"].tobytes() == o["rgb"].tobytes()
    assert results[1].observation["depth"].tobytes() == o["depth"].tobytes()


# async: each env in a process of its own, made from the spec; spawned, since this process has rendered already
# and numba's OpenMP threads do not survive a fork (docs/rollout.md)
@pytest.mark.parametrize("mode, vector_kwargs", [("sync", {}), ("async", {"context": "spawn"})])
def test_gymnasiums_own_vector_envs_step_each_env_as_alone_and_autoreset_to_the_next_episode(tiny_run, mode,
                                                                                          vector_kwargs):
    cfg = {"width": 16, "height": 12, "observations": ["rgb"], "max_steps": 2, "privileged": ["pose"]}
    alone = [NavEnv(tiny_run, cfg) for _ in range(2)]
    alone[0].reset(seed=0)  # renders here before the vector env starts its processes
    vec = gymnasium.make_vec("sagebench.env:sagebench/Nav-v0", num_envs=2, vectorization_mode=mode,
                             vector_kwargs=vector_kwargs, run_dir=str(tiny_run), config=cfg)
    obs, info = vec.reset(seed=7)  # env k gets seed 7 + k
    firsts = [env.reset(seed=7 + k) for k, env in enumerate(alone)]
    assert list(info["episode_id"]) == [i["episode_id"] for _, i in firsts]
    actions = [[Action.MOVE_FORWARD, Action.TURN_LEFT], [Action.TURN_RIGHT, Action.MOVE_FORWARD]]
    for step in actions:
        obs, reward, terminated, truncated, info = vec.step(np.array(step))
        for k, env in enumerate(alone):
            o, r, te, tr, i = env.step(step[k])
            assert obs["rgb"][k].tobytes() == o["rgb"].tobytes() and obs["pose"][k].tolist() == o["pose"].tolist()
            assert (reward[k], terminated[k], truncated[k]) == (r, te, tr)
    assert truncated.all()  # the step limit; gymnasium resets each env on the next step, ignoring its action
    obs, reward, *_ , info = vec.step(np.array([Action.STOP, Action.STOP]))
    nexts = [env.reset() for env in alone]  # the next episode of each env's seeded order
    assert list(info["episode_id"]) == [i["episode_id"] for _, i in nexts] and not reward.any()
    assert [obs["rgb"][k].tobytes() for k in range(2)] == [o["rgb"].tobytes() for o, _ in nexts]
    vec.close()


class _Policy(BaseHTTPRequestHandler):
    """Moves forward twice, then stops; records what it was sent."""

    seen: list[dict] = []

    def do_POST(self):  # noqa: N802 - http.server's name
        body = decode_request(self.headers["Content-Type"], self.rfile.read(int(self.headers["Content-Length"])))
        _Policy.seen.append(body)
        reply = json.dumps({"action": "MOVE_FORWARD" if body[0]["step"] < 2 else "STOP"}).encode()
        self.send_response(200)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(reply)))
        self.end_headers()
        self.wfile.write(reply)

    def log_message(self, *args):
        pass


@pytest.fixture
def policy_server():
    server = ThreadingHTTPServer(("127.0.0.1", 0), _Policy)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    _Policy.seen = []
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/act"
    finally:
        server.shutdown()
        thread.join(timeout=10)


def test_an_http_policy_server_drives_an_episode(demo_eval_run, policy_server, tmp_path, run_cli):
    out = tmp_path / "p.jsonl"
    code, stdout, err = run_cli("rollout", "--run", demo_eval_run, "--policy", policy_server, "--out", out,
                                "--episodes", "1", "--width", "32", "--height", "24", "--obs", "rgb,depth")
    assert code == 0, err
    (row,) = [json.loads(line) for line in out.read_text().splitlines()]
    assert len(row["poses"]) == 3 and row["stopped"] and row["intensity_source"] == "simulator"
    assert [b["step"] for b, _ in _Policy.seen] == [0, 1, 2]
    first, images = _Policy.seen[0]
    assert len(first["episode_id"]) == 16 and first["episode_id"] != row["episode_id"]  # opaque
    assert first["instruction"] and "pose" not in first and first["profile"] == "custom"
    assert images["rgb"].shape == (24, 32, 3)
    depth = images["depth"]
    assert depth.shape == (24, 32) and depth.dtype == np.float32 and depth.max() > 0
    assert (tmp_path / "p_contact_sheet.png").is_file()
    assert stdout.startswith("rollout http://127.0.0.1:")
    step = np.hypot(*(np.array(row["poses"][1][:2]) - row["poses"][0][:2]))
    assert step == pytest.approx(0.25, abs=1e-5) or row["collision_intensity"][1] > 0


def test_rollout_predictions_are_scored_as_measured(demo_eval_run, tmp_path, run_cli):
    out = tmp_path / "s.jsonl"
    assert run_cli("rollout", "--run", demo_eval_run, "--policy", "straight", "--out", out, "--obs", "none")[0] == 0
    assert not (tmp_path / "s_contact_sheet.png").exists()
    res = tmp_path / "r.json"
    code, stdout, _ = run_cli("evaluate", "--run", demo_eval_run, "--predictions", out, "--out", res)
    assert code == 0
    data = json.loads(res.read_text())
    assert data["icp_source"] == {"measured": data["episodes"], "self-reported": 0, "derived": 0}
    assert f"ICP from c(t) measured in {data['episodes']} episodes" in stdout


@pytest.mark.parametrize("args, message", [
    (("--policy", "nope"), "error: --policy: 'nope' is neither an http(s):// URL, sage+http:// or sage+socket:// URL, "
     "vlnce:MODULE:NAME nor one of oracle, straight, random, stationary, explorer"),
    (("--obs", "rgb,colour"), "error: --obs: 'colour' is not one of rgb, depth (or none)"),
    (("--obs", "rgb,instance"), "error: --obs: instance ids are privileged: ask for them with --privileged instance"),
    (("--width", "0"), "error: --width: "),
])
def test_bad_options_are_one_line_and_write_nothing(demo_eval_run, tmp_path, run_cli, args, message):
    out = tmp_path / "p.jsonl"
    code, stdout, err = run_cli("rollout", "--run", demo_eval_run, "--out", out, *args)
    assert code == 2 and err.startswith(message) and len(err.strip().splitlines()) == 1, err
    assert not list(tmp_path.iterdir())


def test_an_unreachable_policy_server_fails_its_episodes_and_says_how_to_resume(demo_eval_run, tmp_path, run_cli):
    out = tmp_path / "p.jsonl"
    code, stdout, err = run_cli("rollout", "--run", demo_eval_run, "--out", out, "--obs", "none", "--episodes", "1",
                                "--policy", "http://127.0.0.1:9/act", "--policy-retries", "1")
    record = json.loads((tmp_path / "p_rollout.json").read_text())
    (eid,) = record["episodes"]
    assert code == 1 and not err and out.read_text() == "" and not record["complete"]
    assert f"  FAILED by the policy: {eid}: policy http://127.0.0.1:9/act (step 0): connection error: " in stdout
    assert "1 episodes to go: sagebench rollout --resume" in stdout
    assert [f["episode_id"] for f in record["failed_by_policy"]] == [eid]


def test_turning_in_place_beside_a_wall_scores_no_contact(demo_eval_run):
    from sagebench.replay.contact import contact_share

    env = NavEnv(demo_eval_run, BLIND.model_copy(update={"max_steps": 80}))
    for seed in range(10):  # walk straight ahead until a wall stops the agent dead
        env.reset(seed=seed)
        while True:
            obs, _, terminated, truncated, info = env.step(Action.MOVE_FORWARD)
            if info["collision_intensity"] > 0.9 or terminated or truncated:
                break
        if info["collision_intensity"] > 0.9:
            break
    assert info["collision_intensity"] > 0.9, "no episode walked into a wall"
    pressed = obs["pose"]
    obs, _, _, _, info = env.step(Action.TURN_LEFT)
    rm = env.sim.world(env.sim.slots[0].episode.scene_id).model
    assert contact_share(rm, [np.array([pressed, obs["pose"]])])[0][1] == 1.0  # within 1 cm of the wall
    assert info["collision_intensity"] == 0.0 and obs["pose"][:2].tolist() == pytest.approx(pressed[:2].tolist(), abs=1e-3)


def test_each_step_hands_out_arrays_of_its_own_and_an_opaque_episode_id(tiny_run):
    """An agent that edits an observation in place changes no later one; info names the episode as a policy server
    would (opaque), the run's id only to an env given privileged observations."""
    env = NavEnv(tiny_run, {"profile": "vlnce", "max_steps": 5})
    obs, info = env.reset(seed=0)
    real = env.sim.slots[0].episode.episode_id
    assert re.fullmatch("[0-9a-f]{16}", info["episode_id"]) and info["episode_id"] != real
    tokens = obs["instruction_tokens"].copy()
    obs["instruction_tokens"][:] = 0
    after, *_, info_after = env.step(Action.TURN_LEFT)
    assert after["instruction_tokens"].tolist() == tokens.tolist() and tokens.any()
    assert info_after["episode_id"] == info["episode_id"]
    told = NavEnv(tiny_run, {"profile": "vlnce", "privileged": ["gps_compass"]}).reset(options={"episode_id": real})
    assert told[1]["episode_id"] == real
