"""The dataset card at a run's root: `datasets.load_dataset(RUN)` gives the episodes by split (not the PNG
frames), and the validation results as their own config."""

from __future__ import annotations

import json

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
    """Two scenes' episodes (scene b held out), validation rows of scene a, their PNG previews, report and
    frames where the stages write them (previews/, reports/), and each scene's scene.json."""
    for scene, splits in SPLITS.items():
        rows = [_row(i, scene_id=scene, episode_id=f"{scene}{i}", split=s) for i, s in enumerate(splits)]
        write_shards(rows, tmp_path / "episodes" / scene, shard_bytes=2**27)
        (tmp_path / "previews" / scene).mkdir(parents=True)
        (tmp_path / "previews" / scene / "paths.png").write_bytes(b"\x89PNG\r\n\x1a\n")
        (tmp_path / "scenes" / scene).mkdir(parents=True)
        (tmp_path / "scenes" / scene / "scene.json").write_text(json.dumps({"scene_id": scene, "license": "cc0-1.0"}))
    (tmp_path / "reports" / "a" / "frames").mkdir(parents=True)
    (tmp_path / "reports" / "a" / "report.json").write_text("{}")
    (tmp_path / "reports" / "a" / "frames" / "contact_sheet.png").write_bytes(b"\x89PNG\r\n\x1a\n")
    (tmp_path / "validation" / "a").mkdir(parents=True)
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


def front_matter(text: str) -> dict:
    return json.loads(text.split("---\n")[1])  # JSON is YAML's flow style


def test_card_declares_licence_task_language_and_size(run):
    meta = front_matter(card_text(run))
    assert (meta["license"], meta["task_categories"], meta["language"], meta["size_categories"]) == \
        ("cc0-1.0", ["robotics"], ["en"], ["n<1K"])
    (run / "scenes" / "b" / "scene.json").write_text(json.dumps({"scene_id": "b", "license": "cc-by-4.0"}))
    assert front_matter(card_text(run))["license"] == "other"  # two licences: the card body lists each scene's
    assert "- `b`: cc-by-4.0" in card_text(run)
    (run / "scenes" / "b" / "scene.json").write_text(json.dumps({"scene_id": "b"}))
    assert front_matter(card_text(run))["license"] == "unknown"


@pytest.mark.parametrize(("rows", "category"), [(0, "n<1K"), (999, "n<1K"), (1000, "1K<n<10K"),
                                                (123_456, "100K<n<1M"), (10**10, "n>1B")])
def test_size_categories_are_the_hubs(rows, category):
    from sagebench.episodes.card import size_category

    assert size_category(rows) == category


@pytest.mark.parametrize("reader", ["pandas", "polars", "duckdb", "pyarrow"])
@pytest.mark.parametrize(("folder", "rows"), [("episodes", 6), ("validation", 2)])
def test_episodes_and_validation_read_as_directories(run, reader, folder, rows):
    """Each folder holds Parquet only (the previews, report and frames live in previews/ and reports/), so every
    common reader takes it as one table."""
    path = str(run / folder)
    if reader == "pandas":
        import pandas as pd

        n = len(pd.read_parquet(path))
    elif reader == "polars":
        import polars as pl

        n = pl.read_parquet(path).height
    elif reader == "duckdb":
        import duckdb

        ((n,),) = duckdb.sql(f"SELECT count(*) FROM read_parquet('{path}')").fetchall()
    else:
        n = pq.read_table(path).num_rows
    assert n == rows
