"""`sagebench export-vlnce`: the demo run as a VLN-CE dataset, read back as habitat would read it."""

from __future__ import annotations

import dataclasses
import gzip
import json
import math
import os
import re

import numpy as np
import pyarrow.parquet as pq
import pytest
import trimesh

from sagebench.scene.loader import load_scene
from sagebench.vlnce.frame import from_habitat, rotation_to_yaw, to_habitat
from tests.test_vlnce import check_habitat_episode

SCENE = "demo_apartment_0"


@pytest.fixture(scope="module")
def export(demo_eval_run, tmp_path_factory):
    from sagebench.cli import main

    out = tmp_path_factory.mktemp("vlnce")
    with pytest.raises(SystemExit) as exc:
        main(["export-vlnce", str(demo_eval_run), "--out", str(out)])
    assert exc.value.code in (0, None)
    return out


def _read(path):
    with gzip.open(path, "rt") as fh:
        return json.load(fh)


def test_each_split_file_holds_its_rows_in_habitat_types(export, demo_eval_run):
    rows = pq.read_table(demo_eval_run / "episodes" / SCENE).to_pylist()
    splits = sorted({r["split"] for r in rows})
    assert sorted(p.name for p in export.iterdir() if p.name != ".sagebench.lock") == \
        sorted([*splits, "scenes", "vlnce_opts.txt", "vocab.txt"])
    by_id = {r["episode_id"]: r for r in rows}
    seen = 0
    for split in splits:
        data = _read(export / split / f"{split}.json.gz")
        words = data["instruction_vocab"]["word_list"]
        assert words[:2] == ["<pad>", "<unk>"] and (export / "vocab.txt").read_text().splitlines() == words
        for ep in data["episodes"]:
            check_habitat_episode(ep)
            row = by_id[ep["episode_id"]]
            assert row["split"] == split
            # back in the world frame, everything is the row's
            assert np.allclose(from_habitat(ep["start_position"]), row["start_position"])
            assert np.allclose(from_habitat(ep["goals"][0]["position"]), row["goal_position"])
            assert np.allclose(from_habitat(ep["reference_path"]), np.array(row["reference_path"])[:, :3])
            assert math.remainder(rotation_to_yaw(ep["start_rotation"]) - row["start_yaw"], 2 * math.pi) == \
                pytest.approx(0.0, abs=1e-9)
            assert ep["info"]["geodesic_distance"] == row["geodesic_distance"]
            tokens = [t for t in ep["instruction"]["instruction_tokens"] if t != 0]
            assert [words[t] for t in tokens] == re.findall(r"'s|[\w-]+", row["instruction_text"].lower())
            assert (export / "scenes" / ep["scene_id"]).is_file()
            seen += 1
    assert seen == len(rows)


def test_scene_glb_is_the_scene_in_habitat_frame(export, demo_eval_run):
    glb = trimesh.load(export / "scenes" / SCENE / f"{SCENE}.glb", force="scene")
    scene = load_scene(demo_eval_run / "scenes" / SCENE)
    assert len(glb.geometry) == len(scene.spec.objects)
    world = np.concatenate([m.vertices for m in scene.meshes.values()])
    expect = to_habitat(world)
    assert np.allclose(glb.bounds, [expect.min(axis=0), expect.max(axis=0)], atol=1e-5)
    assert glb.bounds[0, 1] == pytest.approx(world[:, 2].min(), abs=1e-5)  # habitat's up is the world's


def test_same_run_gives_the_same_bytes(export, demo_eval_run, tmp_path, run_cli):
    assert run_cli("export-vlnce", demo_eval_run, "--out", tmp_path)[0] == 0
    for path in sorted(p for p in export.rglob("*") if p.is_file()):
        want = path.read_bytes()
        if path.name == "vlnce_opts.txt":  # names the dataset by its absolute path
            want = want.replace(str(export.resolve()).encode(), str(tmp_path.resolve()).encode())
        assert (tmp_path / path.relative_to(export)).read_bytes() == want, path


@pytest.mark.parametrize(("split", "message"), [
    ("nope", "error: --split: 'nope' is not a split (one of train, val_seen, val_unseen, test, trajectory_unseen, instruction_unseen)\n"),
    ("train", "no episodes with an instruction in split 'train'\n"),
])
def test_bad_split_exits_2_and_writes_nothing(demo_eval_run, tmp_path, run_cli, split, message):
    rows = pq.read_table(demo_eval_run / "episodes" / SCENE).column("split").to_pylist()
    assert "train" not in rows  # the demo's one scene is held out whole
    code, out, err = run_cli("export-vlnce", demo_eval_run, "--out", tmp_path / "out", "--split", split)
    assert code == 2 and err.endswith(message) and len(err.splitlines()) == 1
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------ read back along VLN-CE's own code paths
@dataclasses.dataclass(kw_only=True)
class NavigationGoal:  # habitat.tasks.nav.nav.NavigationGoal
    position: list
    radius: float | None = None


@dataclasses.dataclass(kw_only=True)
class InstructionData:  # habitat.tasks.vln.vln.InstructionData
    instruction_text: str
    instruction_tokens: list | None = None


@dataclasses.dataclass(kw_only=True)
class VLNExtendedEpisode:  # habitat_extensions.task.VLNExtendedEpisode (attrs: unknown keys are a TypeError)
    episode_id: str
    scene_id: str
    start_position: list
    start_rotation: list
    info: dict | None = None
    goals: list | None = None
    reference_path: list | None = None
    instruction: dict | None = None
    trajectory_id: int | str | None = None


def vlnce_config(export) -> dict[str, str]:
    """The options export-vlnce wrote, as yacs merges them (`KEY VALUE` pairs after run.py's arguments)."""
    words = (export / "vlnce_opts.txt").read_text().split()
    return dict(zip(words[::2], words[1::2]))


def vlnce_dataset(config: dict[str, str], split: str) -> list[VLNExtendedEpisode]:
    """VLNCEDatasetV1(config).episodes: DATA_PATH.format(split=SPLIT) read gzipped, ids cast to str, the scene
    path joined to SCENES_DIR, instruction and goals made into their classes."""
    with gzip.open(config["TASK_CONFIG.DATASET.DATA_PATH"].format(split=split), "rt") as f:
        deserialized = json.loads(f.read())
    assert deserialized["instruction_vocab"]["word_list"]  # VocabDict(word_list=...)
    out = []
    for episode in deserialized["episodes"]:
        episode["episode_id"] = str(episode["episode_id"])
        episode["trajectory_id"] = str(episode["trajectory_id"])
        episode = VLNExtendedEpisode(**episode)
        episode.scene_id = os.path.join(config["TASK_CONFIG.DATASET.SCENES_DIR"], episode.scene_id)
        episode.instruction = InstructionData(**episode.instruction)
        episode.goals = [NavigationGoal(**g) for g in episode.goals]
        out.append(episode)
    return out


def habitat_forward(rotation: np.ndarray) -> np.ndarray:
    """The agent's forward (habitat's -Z) under a rotation [x, y, z, w]."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(rotation).apply([0.0, 0.0, -1.0])


def test_vlnce_loader_reads_episodes_and_gt_of_every_split(export, demo_eval_run):
    """Every split through VLN-CE's dataset loader, NDTW measure (gt_json[episode_id]["locations"], nDTW of the
    teacher's own path 1) and recollect trainer (gt_file.format(split) -> actions per episode, its episode ids the
    dataset's); the gt actions, replayed in habitat's frame from the episode's start pose (MOVE_FORWARD 0.25 m
    along -Z, TURN_LEFT 15 degrees about +Y), visit exactly the gt locations and stop within the success
    distance of the goal."""
    from scipy.spatial.transform import Rotation

    config = vlnce_config(export)
    splits = sorted({r["split"] for r in pq.read_table(demo_eval_run / "episodes" / SCENE).to_pylist()})
    assert config["EVAL.SPLIT"] in splits and config["TASK_CONFIG.DATASET.SPLIT"] in splits
    success = float(config["TASK_CONFIG.TASK.SUCCESS.SUCCESS_DISTANCE"])
    for split in splits:
        episodes = vlnce_dataset(config, split)
        with gzip.open(config["TASK_CONFIG.TASK.NDTW.GT_PATH"].format(split=split), "rt") as f:
            gt_json = json.load(f)
        with gzip.open(config["IL.RECOLLECT_TRAINER.gt_file"].format(split=split)) as f:
            assert json.load(f) == gt_json
        assert sorted(gt_json) == sorted(e.episode_id for e in episodes)  # episodes_allowed = the gt's keys
        for episode in episodes:
            assert os.path.isfile(episode.scene_id)
            gt = gt_json[episode.episode_id]
            locations, actions = np.array(gt["locations"]), gt["actions"]
            assert actions[-1] == 0 and 0 not in actions[:-1] and gt["forward_steps"] == actions.count(1)
            pos, rot = np.array(episode.start_position, float), Rotation.from_quat(episode.start_rotation)
            visited = [pos.copy()]
            for a in actions:
                if a == 1:
                    pos = pos + 0.25 * rot.apply([0.0, 0.0, -1.0])
                    visited.append(pos.copy())
                elif a in (2, 3):
                    rot = Rotation.from_rotvec([0.0, math.radians(15) * (1 if a == 2 else -1), 0.0]) * rot
            assert np.allclose(visited, locations, atol=1e-9)
            goal = np.array(episode.goals[0].position)
            assert np.hypot(*(locations[-1] - goal)[[0, 2]]) < success
            assert np.allclose(locations[0], episode.start_position)


def test_overrides_name_the_vocabulary_and_success_distance(export, demo_eval_run):
    config = vlnce_config(export)
    words = (export / "vocab.txt").read_text().splitlines()
    assert config["MODEL.INSTRUCTION_ENCODER.vocab_size"] == str(len(words))
    assert config["MODEL.INSTRUCTION_ENCODER.use_pretrained_embeddings"] == "False"
    radius = {r["goal_radius"] for r in pq.read_table(demo_eval_run / "episodes" / SCENE).to_pylist()}
    assert {float(config[f"TASK_CONFIG.TASK.{m}.SUCCESS_DISTANCE"]) for m in ("SUCCESS", "SPL", "ORACLE_SUCCESS")} \
        == radius
    assert config["TASK_CONFIG.TASK.NDTW.SUCCESS_DISTANCE"] == "3"  # nDTW's d_th, as sagebench evaluate's
    splits = {r["split"] for r in pq.read_table(demo_eval_run / "episodes" / SCENE).to_pylist()}
    # VLN-CE's configs evaluate on val_unseen: the split named is that where the run has it
    assert config["EVAL.SPLIT"] == next(s for s in ("val_unseen", "val_seen", "test", "train") if s in splits)
