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


def test_temporaries_carry_sagebench_tag(tmp_path, monkeypatch):
    import os

    from sagebench.fileio import is_temporary

    seen = []
    real_replace = os.replace
    monkeypatch.setattr(os, "replace", lambda src, dst: (seen.extend((Path(src).name, Path(dst).name)),
                                                          real_replace(src, dst)))
    write_bytes(tmp_path / "f.bin", b"x")
    with staged_dir(tmp_path / "d") as tmp:
        (tmp / "a").write_text("1")
    with staged_dir(tmp_path / "d") as tmp:  # replacing: the old directory goes aside under a tagged name
        (tmp / "b").write_text("2")
    names = [n for n in seen if n not in ("f.bin", "d")]
    assert len(seen) == 8 and len(names) == 4 and all(is_temporary(n) for n in names), seen
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d", "f.bin"]


@pytest.mark.parametrize("name, ours", [
    (".f.bin.sagebench-ab12cd_z.tmp", True), (".scenes.sagebench-0123abcd.old", True),
    (".x.old", False), (".y.tmp", False), (".f.bin.sagebench-ab12cd.tmp", False),  # 6 random characters
    (".f.bin.abcdefgh.tmp", False), ("f.bin.sagebench-ab12cdzz.tmp", False), (".f.sagebench-ab12cdzz.tmpx", False),
])
def test_is_temporary_matches_only_sagebench_names(name, ours):
    from sagebench.fileio import is_temporary

    assert is_temporary(name) is ours


def test_remove_temporaries_keeps_user_files_and_input_scenes(tmp_path):
    from sagebench.fileio import remove_temporaries

    run = tmp_path / "run"
    ours = [run / "scenes" / "s" / ".topdown.npz.sagebench-abcdefgh.tmp",
            run / "scenes" / ".s.sagebench-01234567.old" / "scene.json", run / ".manifest.json.sagebench-zzzzzzzz.tmp"]
    theirs = [run / ".x.old", run / ".y.tmp", run / "scenes" / "s" / ".x.old", run / "notes" / ".z.sagebench-abcdefgh.tmp",
              run / "scenes" / "input" / ".a.sagebench-abcdefgh.tmp", run / "scenes" / "input" / ".y.tmp"]
    for p in ours + theirs:
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text("x")
    removed = remove_temporaries([run / "scenes"], entries_of=[run], keep_out=[run / "scenes" / "input"])
    assert removed == sorted([ours[0], ours[1].parent, ours[2]])
    assert all(p.exists() for p in theirs) and not any(p.exists() for p in ours)


@pytest.mark.parametrize("umask, file_mode, dir_mode", [(0o022, 0o644, 0o755), (0o077, 0o600, 0o700),
                                                        (0o002, 0o664, 0o775)])
def test_outputs_get_the_modes_of_the_umask(tmp_path, umask, file_mode, dir_mode):
    import os
    import stat

    old = os.umask(umask)
    try:
        write_bytes(tmp_path / "f.bin", b"x")
        with staged_dir(tmp_path / "d") as tmp:
            write_bytes(tmp / "sub" / "g.bin", b"y")
        (tmp_path / "plain").mkdir()
        (tmp_path / "plain.txt").write_text("z")  # what open() and mkdir() give under this umask
    finally:
        os.umask(old)
    modes = {p.name: stat.S_IMODE(p.stat().st_mode) for p in tmp_path.rglob("*")}
    assert modes == {"f.bin": file_mode, "d": dir_mode, "sub": dir_mode, "g.bin": file_mode,
                     "plain": modes["d"], "plain.txt": modes["f.bin"]}
    assert modes["plain"] == dir_mode and modes["plain.txt"] == file_mode
