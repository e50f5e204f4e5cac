"""The dataset card at a run's root: `datasets.load_dataset(RUN)` gives the episodes by split (not the PNG
frames), and the validation results as their own config."""

from __future__ import annotations

import datasets
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from sagebench.episodes.card import card_text
from sagebench.episodes.shards import write_shards
from tests.test_episodes import _row

SPLITS = {"a": ["train", "train", "val_seen", "train"], "b": ["val_unseen", "val_unseen"]}


@pytest.fixture
def run(tmp_path):
    """Two scenes' episodes (scene b held out), validation rows of scene a, and PNGs that must not load."""
    for scene, splits in SPLITS.items():
        rows = [_row(i, scene_id=scene, episode_id=f"{scene}{i}", split=s) for i, s in enumerate(splits)]
        write_shards(rows, tmp_path / "episodes" / scene, shard_bytes=2**27)
        (tmp_path / "episodes" / scene / "_preview").mkdir()
        (tmp_path / "episodes" / scene / "_preview" / "paths.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    (tmp_path / "validation" / "a" / "frames").mkdir(parents=True)
    pq.write_table(pa.table({"trajectory_id": ["t0", "t1"], "passed": [True, False]}),
                   tmp_path / "validation" / "a" / "part-00000.parquet")
    (tmp_path / "README.md").write_text(card_text(tmp_path))
    return tmp_path


def test_load_dataset_gives_episodes_by_split_and_validation(run, tmp_path_factory, monkeypatch):
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    cache = tmp_path_factory.mktemp("hf_cache")
    episodes = datasets.load_dataset(str(run), cache_dir=str(cache))
    assert sorted(episodes) == ["train", "val_seen", "val_unseen"]
    assert sorted(episodes["train"]["episode_id"]) == ["a0", "a1", "a3"]
    assert episodes["val_unseen"]["episode_id"] == ["b0", "b1"] and episodes["val_seen"]["split"] == ["val_seen"]
    assert episodes["train"].features["reference_path"].feature.feature.dtype == "float64"
    results = datasets.load_dataset(str(run), "validation", cache_dir=str(cache))
    assert results["trajectories"]["passed"] == [True, False]


def test_card_names_only_splits_that_have_shards_and_every_column(run):
    text = card_text(run)
    assert '"split": "test"' not in text and '"split": "val_seen"' in text
    assert text.startswith("---\n{") and "| `goal_radius` | Success radius around goal_position, metres. |" in text
    assert card_text(run) == text
