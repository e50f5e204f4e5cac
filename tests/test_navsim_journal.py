"""The rollout's predictions file while it runs: whole lines on disk as episodes finish, a torn last line dropped on
resume, run order once complete (the bytes an uninterrupted rollout writes)."""

from __future__ import annotations

import pytest

from sagebench.errors import DataError
from sagebench.evaluation.predictions import Prediction, dumps_prediction
from sagebench.navsim.journal import Journal


def prediction(eid: str, x: float = 0.0) -> Prediction:
    return Prediction(episode_id=eid, poses=[(x, 0.0, 0.0, 0.0), (x + 0.25, 0.0, 0.0, 0.0)], stopped=True,
                      collision_intensity=[0.0, 0.0], intensity_source="simulator")


def test_each_episode_is_on_disk_as_it_finishes_and_run_order_at_the_end(tmp_path):
    out = tmp_path / "p.jsonl"
    out.write_text("stale\n")
    journal = Journal(out, {})
    assert out.read_text() == ""  # a fresh rollout starts an empty file
    journal.append(prediction("b", 1.0))
    assert out.read_text() == dumps_prediction(prediction("b", 1.0)) + "\n"
    journal.append(prediction("a"))
    journal.finish(["a", "b"])
    assert out.read_text() == "".join(dumps_prediction(p) + "\n" for p in (prediction("a"), prediction("b", 1.0)))


def test_resume_keeps_whole_lines_and_drops_a_torn_one(tmp_path):
    out = tmp_path / "p.jsonl"
    whole = dumps_prediction(prediction("c")) + "\n"
    out.write_text(whole + dumps_prediction(prediction("a"))[:17])  # killed inside the second write
    journal = Journal.resume(out, ["a", "b", "c"])
    assert list(journal.lines) == ["c"] and out.read_text() == whole
    journal.append(prediction("a"))
    journal.append(prediction("b", 2.0))
    journal.finish(["a", "b", "c"])
    clean = Journal(tmp_path / "clean.jsonl", {})
    for p in (prediction("b", 2.0), prediction("c"), prediction("a")):
        clean.append(p)
    clean.finish(["a", "b", "c"])
    assert out.read_bytes() == (tmp_path / "clean.jsonl").read_bytes()


def test_resume_of_a_missing_file_starts_empty(tmp_path):
    assert Journal.resume(tmp_path / "none.jsonl", ["a"]).lines == {}


@pytest.mark.parametrize("text, message", [
    (dumps_prediction(prediction("z")) + "\n", "p.jsonl:1: episode_id: episode 'z' is not one this rollout was asked to run"),
    (2 * (dumps_prediction(prediction("a")) + "\n"), "p.jsonl:2: episode_id: duplicate episode id 'a'"),
    ('{"episode_id": "a"}\n', "p.jsonl:1: poses: Field required"),
])
def test_resume_refuses_lines_that_are_not_this_rollouts(tmp_path, text, message):
    out = tmp_path / "p.jsonl"
    out.write_text(text)
    with pytest.raises(DataError) as err:
        Journal.resume(out, ["a", "b"])
    assert str(err.value) == f"{tmp_path}/{message}"
    assert out.read_text() == text  # nothing rewritten
