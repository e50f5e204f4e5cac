"""Splits: unseen splits hold whole scenes, seen splits share scenes with train; deterministic and stable."""

from __future__ import annotations

import random
from collections import Counter

import pytest
from pydantic import ValidationError

from sagebench.episodes.splits import assign_splits, scene_split
from sagebench.settings.gen_trajectories import SplitConfig

TRAJ = [f"{i:016x}" for i in range(200)]


def test_a_held_out_scene_puts_every_trajectory_in_its_split():
    config = SplitConfig(val_unseen=0.5, test=0.5)  # every scene held out
    splits = {sid: set(assign_splits(sid, TRAJ, config).values()) for sid in (f"scene_{i}" for i in range(40))}
    assert all(len(s) == 1 for s in splits.values())
    counts = Counter(next(iter(s)) for s in splits.values())
    assert set(counts) == {"val_unseen", "test"}


def test_a_seen_scene_sends_the_configured_share_of_trajectories_to_val_seen():
    config = SplitConfig(val_unseen=0.0, test=0.0, val_seen=0.15)
    got = assign_splits("apt", TRAJ, config)
    assert Counter(got.values()) == {"val_seen": 30, "train": 170}  # round(200 * 0.15) exactly
    shuffled = TRAJ[:]
    random.Random(1).shuffle(shuffled)
    assert assign_splits("apt", shuffled, config) == got  # order of the trajectories does not matter
    assert assign_splits("apt", TRAJ, config.model_copy(update={"seed": 1})) != got  # the seed does


def test_scene_fractions_hold_over_many_scenes():
    config = SplitConfig(val_unseen=0.1, test=0.2)
    scenes = [f"scene_{i}" for i in range(3000)]
    counts = Counter(scene_split(s, config) for s in scenes)
    # binomial standard deviation at n = 3000: 0.0055 (p = 0.1), 0.0073 (p = 0.2); allow 4 of them
    assert counts["val_unseen"] / 3000 == pytest.approx(0.1, abs=0.022)
    assert counts["test"] / 3000 == pytest.approx(0.2, abs=0.03)


def test_held_out_fractions_above_one_are_refused():
    with pytest.raises(ValidationError, match="val_unseen \\+ test is 1.2"):
        SplitConfig(val_unseen=0.6, test=0.6)


def test_sages_test_splits_are_named_and_deterministic():
    from sagebench.episodes.splits import instruction_held_out
    from sagebench.settings.shared import SAGE_SPLITS

    config = SplitConfig(val_unseen=0, test=0, val_seen=0.1, trajectory_unseen=0.2, instruction_unseen=0.25)
    ids = [f"{i:016x}" for i in range(200)]
    split_of = assign_splits("seen", ids, config)
    assert Counter(split_of.values()) == {"val_seen": 20, "trajectory_unseen": 40, "train": 140}
    held = instruction_held_out(split_of, config)
    assert len(held) == 35 and all(split_of[t] == "train" for t in held)  # seen trajectories, held-out phrasing
    assert (split_of, held) == (assign_splits("seen", ids[::-1], config), instruction_held_out(split_of, config))
    assert SAGE_SPLITS == {"Scene-Unseen": "test", "Trajectory-Unseen": "trajectory_unseen",
                           "Instruction-Unseen": "instruction_unseen"}
    assert set(assign_splits("held", ids, SplitConfig(test=1.0, val_unseen=0, trajectory_unseen=0.5)).values()) \
        == {"test"}  # Scene-Unseen: a held-out scene's trajectories stay whole in test


def test_instruction_unseen_takes_only_the_high_level_row_of_a_seen_trajectory(tiny_scene, tmp_path):
    from sagebench.episodes.shards import read_episodes
    from sagebench.settings.build_scene import BuildSceneConfig, SplatConfig
    from sagebench.stages.build_scene import build_scene
    from sagebench.stages.gen_trajectories import GenTrajectoriesConfig, gen_trajectories

    run = tmp_path / "run"
    build_scene(tiny_scene, run, BuildSceneConfig(splats=SplatConfig(object_density=20.0, structure_density=5.0)))
    gen_trajectories(run, GenTrajectoriesConfig(per_scene=4, min_geodesic_m=1.0, splits=SplitConfig(
        val_unseen=0, test=0, val_seen=0, instruction_unseen=1.0)))
    rows = read_episodes(run / "episodes/tiny").to_pylist()
    assert {(r["instruction_level"], r["split"]) for r in rows} == {("low", "train"), ("high", "instruction_unseen")}
    by_trajectory = {r["trajectory_id"] for r in rows if r["split"] == "instruction_unseen"}
    assert by_trajectory == {r["trajectory_id"] for r in rows if r["split"] == "train"}
