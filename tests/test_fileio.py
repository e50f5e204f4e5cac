"""Atomic writes: a failure leaves the previous output untouched and no temporary files behind."""

from pathlib import Path

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


def test_write_bytes_renames_a_complete_temporary_over_the_final_name(tmp_path, monkeypatch):
    import os

    final = tmp_path / "f.bin"
    final.write_bytes(b"old")
    seen = []
    real_replace = os.replace

    def replace(src, dst):  # what a reader could see at the moment of the rename
        seen.append((os.path.dirname(src), Path(src).read_bytes(), Path(dst).read_bytes()))
        real_replace(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    write_bytes(final, b"new" * 1000)
    assert seen == [(str(tmp_path), b"new" * 1000, b"old")]  # same directory, full data, old file untouched
    assert final.read_bytes() == b"new" * 1000


def test_write_bytes_interrupted_keeps_the_old_file(tmp_path, monkeypatch):
    import os

    final = tmp_path / "f.bin"
    final.write_bytes(b"old")

    def interrupted(fd):
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "fsync", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_bytes(final, b"new")
    assert final.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["f.bin"]
