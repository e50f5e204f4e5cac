"""predictions.jsonl: rows read back as written; every bad row names file:line and field; ids are matched strictly."""

from __future__ import annotations

import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from profiles import examples

from sagebench.errors import DataError
from sagebench.evaluation.predictions import (
    Prediction, dumps_prediction, match_episodes, read_predictions, write_predictions,
)

GOOD = {"episode_id": "e1", "poses": [[0, 0, 0, 0], [0.25, 0, 0, 0]], "stopped": True}


def _file(tmp_path, *rows) -> object:
    path = tmp_path / "pred.jsonl"
    path.write_text("".join((r if isinstance(r, str) else json.dumps(r)) + "\n" for r in rows))
    return path


finite = st.floats(-50, 50, allow_nan=False)


@settings(max_examples=examples(30))
@given(st.lists(st.tuples(finite, finite, finite, finite), min_size=1, max_size=6), st.booleans(),
       st.booleans())
def test_write_then_read_round_trips(tmp_path_factory, poses, stopped, with_c):
    c = [0.5] * len(poses) if with_c else None
    preds = [Prediction(episode_id=f"e{i}", poses=poses, stopped=stopped, collision_intensity=c) for i in range(3)]
    path = tmp_path_factory.mktemp("rt") / "p.jsonl"
    write_predictions(path, preds)
    assert [p for _, p in read_predictions(path)] == preds
    assert path.read_text().count("\n") == 3
    assert ("collision_intensity" in path.read_text()) == with_c  # absent, not null, when not given


def test_canonical_line():
    assert dumps_prediction(Prediction(episode_id="a", poses=[(1, 2, 0, 0.5)], stopped=False)) == \
        '{"episode_id":"a","poses":[[1.0,2.0,0.0,0.5]],"stopped":false}'


def test_blank_lines_are_skipped_and_line_numbers_kept(tmp_path):
    path = _file(tmp_path, GOOD, "", "   ", GOOD | {"episode_id": "e2"})
    assert [(n, p.episode_id) for n, p in read_predictions(path)] == [(1, "e1"), (4, "e2")]


@pytest.mark.parametrize("row, message", [
    ("{not json", ":2: Invalid JSON: key must be a string at line 1 column 2"),
    ("[1, 2]", ":2: Input should be an object"),
    (GOOD | {"stopped": 1}, ":2: stopped: Input should be a valid boolean"),
    (GOOD | {"poses": [[0, 0, 0]]}, ":2: poses[0]: a pose is [x, y, z, yaw]: 4 numbers"),
    (GOOD | {"poses": [[0, 0, 0, 0, 0]]}, ":2: poses[0]: Tuple should have at most 4 items after validation, not 5"),
    (GOOD | {"poses": [[0, 0, 0, "1"]]}, ":2: poses[0][3]: Input should be a valid number"),
    (GOOD | {"poses": []}, ":2: poses: List should have at least 1 item after validation, not 0"),
    ('{"episode_id": "e2", "poses": [[0, 0, 0, NaN]], "stopped": true}', ":2: poses[0][3]: Input should be a finite number"),
    (GOOD | {"collision_intensity": [0, 1.5]}, ":2: collision_intensity[1]: Input should be less than or equal to 1"),
    (GOOD | {"collision_intensity": [0]}, ":2: collision_intensity has 1 values for 2 poses (one per pose)"),
    (GOOD | {"collision": [0, 0]}, ":2: collision: Extra inputs are not permitted"),
    ({"poses": [[0, 0, 0, 0]], "stopped": True}, ":2: episode_id: Field required"),
])
def test_bad_rows_name_file_line_and_field(tmp_path, row, message):
    path = _file(tmp_path, GOOD, row)
    with pytest.raises(DataError) as err:
        read_predictions(path)
    assert str(err.value) == f"{path}{message}"


def test_empty_or_absent_file(tmp_path):
    with pytest.raises(DataError, match="no predictions \\(the file is empty\\)"):
        read_predictions(_file(tmp_path, ""))
    with pytest.raises(DataError, match="nope.jsonl: no such file"):
        read_predictions(tmp_path / "nope.jsonl")


def test_ids_are_matched_strictly(tmp_path):
    path = _file(tmp_path, GOOD, GOOD | {"episode_id": "e2"})
    rows = read_predictions(path)
    matched, missing = match_episodes(rows, ["e1", "e2", "e3"], path, allow_missing=True)
    assert sorted(matched) == ["e1", "e2"] and missing == ["e3"]
    with pytest.raises(DataError) as err:
        match_episodes(rows, ["e1", "e2", "e3", "e4", "e5", "e6"], path)
    assert str(err.value) == (f"{path}: 4 of 6 episodes have no prediction (e3, e4, e5, ...); "
                              "pass --allow-missing to score them as failures")
    with pytest.raises(DataError) as err:
        match_episodes(rows, ["e1"], path, allow_missing=True)
    assert str(err.value) == f"{path}:2: episode_id: unknown episode id 'e2': not an episode being evaluated (1 unknown in all)"
    dup = _file(tmp_path, GOOD, GOOD | {"episode_id": "e2"}, GOOD)
    with pytest.raises(DataError) as err:
        match_episodes(read_predictions(dup), ["e1", "e2"], dup)
    assert str(err.value) == f"{dup}:3: episode_id: duplicate episode id 'e1' (first on line 1)"
