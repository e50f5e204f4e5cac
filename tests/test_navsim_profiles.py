"""Observation profiles: vlnce gives what VLN-CE's R2R config gives (its values are written out here from
jacobkrantz/VLN-CE's vlnce_task.yaml and habitat-lab 0.1.7's defaults, not read from our code), and no profile but
full carries pose, GPS/compass or instance ids, in-process, through gymnasium and over HTTP."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from fake_policy import FakePolicy
from sagebench.env import NavEnv
from sagebench.env.gym_env import observation_space
from sagebench.navsim.observe import observe
from sagebench.navsim.profiles import DepthFormat, gps_compass, resolve
from sagebench.navsim.simulator import Simulator
from sagebench.settings.rollout import PROFILES, EnvConfig

PRIVILEGED_KEYS = {"pose", "gps", "compass", "instance"}
# VLN-CE R2R: RGB_SENSOR 224x224 uint8, DEPTH_SENSOR 256x256 (MIN_DEPTH 0, MAX_DEPTH 10, NORMALIZE_DEPTH) as
# [H, W, 1] float32, instruction {text, tokens} with R2R-CE's 200 padded word ids; hfov 90, sensor 1.25 m up
VLNCE = {"rgb": ((224, 224, 3), np.uint8), "depth": ((256, 256, 1), np.float32)}
VLNCE_MAX_DEPTH, VLNCE_TOKENS = 10.0, 200


def test_depth_formats_known_answers():
    d = np.array([[0.0, 2.5, 10.0, 14.0]], np.float32)
    assert DepthFormat(clip=(0.0, 10.0), normalised=True, channel=True).apply(d)[..., 0].tolist() == [[0, 0.25, 1, 1]]
    assert DepthFormat(clip=(0.0, 6.5)).apply(d).tolist() == [[0.0, 2.5, 6.5, 6.5]]
    assert DepthFormat().apply(d).tolist() == d.tolist()


@pytest.mark.parametrize("pose, start, yaw, gps, compass", [
    ((3.0, 2.0, 0.0, 0.0), (1.0, 2.0), 0.0, (2.0, 0.0), 0.0),  # 2 m straight ahead
    ((1.0, 3.0, 0.0, 0.5), (1.0, 2.0), 0.0, (0.0, -1.0), 0.5),  # 1 m to the left is -1 m right; turned 0.5 left
    ((1.0, 3.0, 0.0, math.pi), (1.0, 2.0), math.pi / 2, (1.0, 0.0), math.pi / 2),  # facing +y: 1 m ahead
])
def test_gps_and_compass_are_habitats_episodic_ones(pose, start, yaw, gps, compass):
    g, c = gps_compass(np.array(pose), np.array(start), yaw)
    assert g.dtype == c.dtype == np.float32 and g.shape == (2,) and c.shape == (1,)
    assert g.tolist() == pytest.approx(gps, abs=1e-6) and c[0] == pytest.approx(compass, abs=1e-6)


@pytest.mark.parametrize("profile", PROFILES)
def test_only_full_has_privileged_keys_unless_asked(profile):
    keys = set(resolve(profile).keys)
    assert (keys & PRIVILEGED_KEYS == PRIVILEGED_KEYS) if profile == "full" else not keys & PRIVILEGED_KEYS
    asked = set(resolve(profile, privileged=("pose", "gps_compass", "instance")).keys)
    assert asked >= PRIVILEGED_KEYS and "instruction" in asked


def test_the_vlnce_profile_is_vlnces_observations(demo_eval_run):
    env = NavEnv(demo_eval_run, {"profile": "vlnce", "max_steps": 2})
    obs, info = env.reset(seed=0)
    assert set(obs) == {"rgb", "depth", "instruction", "instruction_tokens"}
    for key, (shape, dtype) in VLNCE.items():
        assert obs[key].shape == shape and obs[key].dtype == dtype and env.observation_space[key].shape == shape
    assert 0.0 <= obs["depth"].min() and obs["depth"].max() <= 1.0 and obs["depth"].max() > 0
    tokens = obs["instruction_tokens"]
    assert tokens.shape == (VLNCE_TOKENS,) and tokens.dtype == np.int64 and env.observation_space.contains(obs)
    words = env.sim.vocabulary.word_list
    assert [words[t] for t in tokens if t] == re.findall(r"[a-z0-9-]+", obs["instruction"].lower())
    s = env.sim.slots[0]  # depth: the metres of a 256x256 render from VLN-CE's camera height, over 0-10 m
    w = env.sim.world(s.episode.scene_id)
    metres = observe(w.renderer, np.array([s.poses[-1]]), ("depth",), floor_z=w.model.floor_z, camera_height=1.25,
                     hfov_deg=90.0, width=256, height=256)["depth"][0]
    assert env.config.camera.height == 1.2  # the profile alone keeps the run's camera; --preset vlnce moves it
    env = NavEnv(demo_eval_run, {"profile": "vlnce", "max_steps": 2, "camera": {"height": 1.25}})
    obs, _ = env.reset(options={"episode_id": s.episode.episode_id})  # info's id is opaque
    expected = np.clip(metres, 0, VLNCE_MAX_DEPTH) / VLNCE_MAX_DEPTH
    assert obs["depth"][..., 0].tobytes() == expected.astype(np.float32).tobytes()


def test_the_tokens_are_export_vlnces_word_ids(demo_eval_run, tmp_path):
    from sagebench.stages.export_vlnce import export_vlnce

    export_vlnce(demo_eval_run, tmp_path / "vlnce")
    sim = Simulator(demo_eval_run, EnvConfig(profile="vlnce"))
    assert (tmp_path / "vlnce" / "vocab.txt").read_text().split("\n")[:-1] == list(sim.vocabulary.word_list)


@pytest.mark.parametrize("profile", PROFILES)
def test_no_profile_but_full_sends_pose_or_instance_ids_on_any_transport(demo_eval_run, tmp_path, run_cli, profile):
    small = {"width": 16, "height": 12} if profile != "vlnce" else {}
    config = EnvConfig(profile=profile, max_steps=1, **small)
    sim = Simulator(demo_eval_run, config)
    (first,) = sim.start(sim.order[:1])
    in_process = set(first.observation)
    gym = set(observation_space(config, [], 10).spaces)
    s = FakePolicy()
    try:
        size = [a for k, v in small.items() for a in (f"--{k}", str(v))]
        code, _, err = run_cli("rollout", "--run", demo_eval_run, "--out", tmp_path / "p.jsonl", "--policy", s.url,
                               "--profile", profile, "--episodes", "1", "--max-steps", "1", *size)
    finally:
        s.close()
    assert code == 0, err
    fields, images = s.seen[0]
    over_http = set(fields) | set(images)
    assert in_process == gym == over_http - {"episode_id", "step", "action_space", "profile"}
    for keys in (in_process, gym, over_http):
        assert (keys >= PRIVILEGED_KEYS) if profile == "full" else not keys & PRIVILEGED_KEYS
