"""Episode rows: the documented columns and types (docs/outputs.md), shards that split and round-trip, byte-identical rewrites."""

import cv2
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from sagebench.episodes.preview import render_paths
from sagebench.episodes.schema import EPISODE_SCHEMA, field_descriptions
from sagebench.episodes.shards import read_episodes, rows_table, table_bytes, write_shards

DESIGN_COLUMNS = ["episode_id", "trajectory_id", "scene_id", "instruction_level", "instruction_type",
                  "instruction_text", "start_instance_id", "goal_instance_id", "start_room", "goal_room",
                  "start_position", "start_yaw", "goal_position", "goal_radius", "reference_path",
                  "geodesic_distance", "instruction_source", "seed", "split"]  # split: issue 14


def _row(i: int, **over):
    row = {"episode_id": f"e{i}", "trajectory_id": f"t{i}", "scene_id": "s", "instruction_level": "low",
           "instruction_type": "Single_Goal", "instruction_text": "Walk from the sofa to the kitchen.",
           "start_instance_id": 3, "goal_instance_id": None, "start_room": "r1", "goal_room": "r2",
           "start_position": [1.0, 2.0, 0.0], "start_yaw": 0.5, "goal_position": [4.0, 2.0, 0.0], "goal_radius": 1.0,
           "reference_path": [[1.0, 2.0, 0.0, 0.5], [4.0, 2.0, 0.0, 0.0]], "geodesic_distance": 3.2,
           "instruction_source": "template", "seed": 7, "split": "train"}
    return {**row, **over}


def test_columns_are_exactly_design_md_in_order():
    assert EPISODE_SCHEMA.names == DESIGN_COLUMNS
    assert EPISODE_SCHEMA.field("start_position").type == pa.list_(pa.float64(), 3)
    assert EPISODE_SCHEMA.field("reference_path").type == pa.list_(pa.list_(pa.float64(), 4))
    assert list(field_descriptions()) == DESIGN_COLUMNS


def test_every_shard_carries_the_column_descriptions(tmp_path):
    (path,) = write_shards([_row(0)], tmp_path, shard_bytes=2**27)
    schema = pq.read_schema(path)
    for name, doc in field_descriptions().items():
        assert schema.field(name).metadata[b"description"].decode() == doc


def test_shards_split_by_bytes_and_round_trip(tmp_path):
    rows = [_row(i) for i in range(7)]
    whole = len(table_bytes(rows_table(rows)))
    paths = write_shards(rows, tmp_path, shard_bytes=whole // 3 + 1)  # needs 3 shards: rows 3, 3, 1
    assert [p.name for p in paths] == ["part-train-00000.parquet", "part-train-00001.parquet",
                                       "part-train-00002.parquet"]
    assert [pq.read_metadata(p).num_rows for p in paths] == [3, 3, 1]
    table = read_episodes(tmp_path)
    assert table.schema == EPISODE_SCHEMA
    assert table.to_pylist() == rows
    assert not list(tmp_path.glob(".*"))  # no temporary files left behind
    assert [p.name for p in write_shards(rows, tmp_path / "one", shard_bytes=whole)] == ["part-train-00000.parquet"]


def test_one_split_per_shard(tmp_path):
    rows = [_row(i, split=s) for i, s in enumerate(["val_seen", "train", "test", "train", "val_seen"])]
    paths = write_shards(rows, tmp_path, shard_bytes=2**27)
    assert [p.name for p in paths] == ["part-test-00000.parquet", "part-train-00000.parquet",
                                       "part-val_seen-00000.parquet"]
    for path in paths:
        split = path.name.split("-")[1]
        assert [r["episode_id"] for r in pq.read_table(path).to_pylist()] == \
            [r["episode_id"] for r in rows if r["split"] == split]


def test_row_groups_hold_about_16_mb(tmp_path, monkeypatch):
    """Row groups sized by bytes: a budget of 2.5 average rows gives groups of 2 rows."""
    import sagebench.episodes.shards as shards

    rows = [_row(i, instruction_text="x" * 2000 + str(i)) for i in range(7)]
    per_row = len(table_bytes(rows_table(rows))) / 7
    monkeypatch.setattr(shards, "ROW_GROUP_BYTES", int(2.5 * per_row))
    (path,) = write_shards(rows, tmp_path, shard_bytes=2**27)
    meta = pq.read_metadata(path)
    assert [meta.row_group(i).num_rows for i in range(meta.num_row_groups)] == [2, 2, 2, 1]


def test_same_rows_give_byte_identical_shards(tmp_path):
    rows = [_row(i) for i in range(5)]
    a = write_shards(rows, tmp_path / "a", 600)
    b = write_shards(rows, tmp_path / "b", 600)
    assert len(a) > 1
    assert [p.read_bytes() for p in a] == [p.read_bytes() for p in b]


def test_a_row_of_the_wrong_shape_is_refused():
    with pytest.raises((pa.ArrowInvalid, pa.ArrowTypeError, ValueError)):
        rows_table([_row(0, start_position=[1.0, 2.0])])


def test_paths_png_is_north_up_with_the_path_drawn():
    nav = np.ones((40, 60), dtype=np.uint8)
    occ = np.zeros_like(nav)
    occ[:5, :] = 1  # blocked strip along the south edge (low y)
    png = render_paths(nav * (1 - occ), occ, [np.array([[0.5, 1.0], [2.5, 1.0]])], 0.05, (0.0, 0.0), max_size_px=600)
    img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    assert img.shape == (400, 600, 3)
    assert (img[-10:, :, :] < 100).all()  # south strip at the bottom, dark
    assert (img[200, 100:480] != 255).any()  # the path at y = 1 m crosses the middle row


@pytest.mark.parametrize("split", ["../../../other/episodes/s/part-train", "", "tr\nain", "train/x"])
def test_a_split_that_is_not_a_split_name_never_names_a_file(split, tmp_path):
    """import-sage-episodes took a split from its file into the shard's name: `../../..` wrote another run's
    shard, and "" or a newline made odd names. The writer is the last line of defence: nothing is written."""
    from sagebench.errors import DataError

    out = tmp_path / "run" / "episodes" / "s"
    out.mkdir(parents=True)
    with pytest.raises(DataError) as err:
        write_shards([_row(0), _row(1, split=split)], out, shard_bytes=2**27)
    assert str(err.value) == f"{out}: split: split {split!r} is not one of train, val_seen, val_unseen, test, " \
                             "trajectory_unseen, instruction_unseen; " \
                             "no shard was written"
    assert [p.relative_to(tmp_path).as_posix() for p in sorted(tmp_path.rglob("*"))] == [
        "run", "run/episodes", "run/episodes/s"]
