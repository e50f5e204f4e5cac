"""Atomic writes: a failure leaves the previous output untouched and no temporary files behind."""

import pytest

from sagebench.fileio import dumps_json, staged_dir, write_bytes


def test_staged_dir_replaces_whole_on_success(tmp_path):
    final = tmp_path / "out"
    with staged_dir(final) as tmp:
        (tmp / "a.txt").write_text("one")
    with staged_dir(final) as tmp:
        (tmp / "b.txt").write_text("two")
    assert sorted(p.name for p in final.iterdir()) == ["b.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_staged_dir_keeps_old_output_on_failure(tmp_path):
    final = tmp_path / "out"
    with staged_dir(final) as tmp:
        (tmp / "a.txt").write_text("one")
    with pytest.raises(RuntimeError), staged_dir(final) as tmp:
        (tmp / "half.txt").write_text("half")
        raise RuntimeError("boom")
    assert [p.name for p in final.iterdir()] == ["a.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_write_bytes_leaves_no_temporary(tmp_path):
    write_bytes(tmp_path / "sub" / "f.bin", b"x")
    assert [p.name for p in (tmp_path / "sub").iterdir()] == ["f.bin"]


def test_canonical_json_is_order_independent():
    assert dumps_json({"b": 1, "a": [1.5, "é"]}) == dumps_json({"a": [1.5, "é"], "b": 1})
