"""`sagebench export-vlnce`: the demo run as a VLN-CE dataset, read back as habitat would read it."""

from __future__ import annotations

import gzip
import json
import math
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
    assert sorted(p.name for p in export.iterdir()) == sorted([*splits, "scenes", "vocab.txt"])
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
        assert (tmp_path / path.relative_to(export)).read_bytes() == path.read_bytes(), path


@pytest.mark.parametrize(("split", "message"), [
    ("nope", "error: --split: 'nope' is not a split (one of train, val_seen, val_unseen, test)\n"),
    ("train", "no episodes with an instruction in split 'train'\n"),
])
def test_bad_split_exits_2_and_writes_nothing(demo_eval_run, tmp_path, run_cli, split, message):
    rows = pq.read_table(demo_eval_run / "episodes" / SCENE).column("split").to_pylist()
    assert "train" not in rows  # the demo's one scene is held out whole
    code, out, err = run_cli("export-vlnce", demo_eval_run, "--out", tmp_path / "out", "--split", split)
    assert code == 2 and err.endswith(message) and len(err.splitlines()) == 1
    assert not (tmp_path / "out").exists()
