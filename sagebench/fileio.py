"""Atomic file and directory writes: a reader never sees a half-written output.

Every temporary is named `.NAME.sagebench-XXXXXXXX.tmp` (or `.old`, for the output a staged directory
replaces), so `remove_temporaries` can tell sagebench's leftovers from anything a user keeps beside them.
Outputs get the modes a plain open() / mkdir() would give under the current umask (mkstemp's 0600 and
mkdtemp's 0700 would otherwise survive the rename).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import secrets
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any, BinaryIO

from sagebench.errors import OutputError
from sagebench.ui import check_interrupted

TEMP_TAG = "sagebench-"
_TEMPORARY = re.compile(r"\..+\.sagebench-[0-9a-z_]{8}\.(tmp|old)")


def is_temporary(name: str) -> bool:
    """Whether a file name is one of sagebench's temporaries (`.NAME.sagebench-XXXXXXXX.tmp` or `.old`)."""
    return _TEMPORARY.fullmatch(name) is not None


def current_umask() -> int:
    """The process umask, read without changing it (os.umask would set it, briefly, for every thread)."""
    with contextlib.suppress(OSError, ValueError):
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def _writing(path: Path) -> Iterator[None]:
    """An OSError of sagebench's own writing becomes one OutputError line naming the path (a file where a
    directory goes or the reverse, no permission, a full disk)."""
    try:
        yield
    except OSError as err:
        raise OutputError(f"cannot write: {err.strerror or err}", path=path) from None


def write_bytes(path: Path, data: bytes) -> None:
    """Write to a temporary sibling, fsync, then rename over `path` (mode 0666 less the umask)."""
    with staged_file(path) as fh:
        fh.write(data)


@contextlib.contextmanager
def staged_file(path: Path) -> Iterator[BinaryIO]:
    """A binary file on a temporary sibling of `path`, for outputs too big to hold in memory: on success it is
    fsynced and renamed over `path` (mode 0666 less the umask), on any error removed."""
    with _writing(path):
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{TEMP_TAG}", suffix=".tmp", dir=path.parent)
        try:
            with os.fdopen(fd, "wb") as fh:
                os.fchmod(fh.fileno(), 0o666 & ~current_umask())
                yield fh
                fh.flush()
                os.fsync(fh.fileno())
            check_interrupted()
            os.replace(tmp, path)
        except BaseException:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
            raise


def copy_file(src: Path, path: Path) -> None:
    """Copy `src` to `path` as write_bytes writes (temporary sibling, fsync, rename), a chunk at a time."""
    with staged_file(path) as fh, open(src, "rb") as source:
        shutil.copyfileobj(source, fh, 1 << 20)


def hash_file(path: Path, h: Any = None) -> Any:
    """`h` (a new sha256 when None) updated with the file's bytes, read a chunk at a time (never whole)."""
    h = hashlib.sha256() if h is None else h
    with Path(path).open("rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h


def sha256_file(path: Path) -> str:
    return hash_file(path).hexdigest()


def write_text(path: Path, text: str) -> None:
    write_bytes(path, text.encode("utf-8"))


def dumps_json(obj: Any) -> str:
    """Canonical JSON (sorted keys, 2-space indent, trailing newline) so equal data gives equal bytes."""
    return json.dumps(obj, indent=2, sort_keys=True, ensure_ascii=False) + "\n"


def write_json(path: Path, obj: Any) -> None:
    write_text(path, dumps_json(obj))


@contextlib.contextmanager
def staged_dir(final: Path, *, keep_hidden: bool = True) -> Iterator[Path]:
    """Yield an empty temporary directory beside `final` (mode 0777 less the umask); on success it replaces
    `final` whole, but for the user's hidden entries there (dotfiles that are not sagebench's temporaries), which
    are moved into the new directory unless not `keep_hidden`: sagebench never deletes a file of the user's.

    On any error the temporary directory is removed and `final` is left as it was.
    """
    with _writing(final):
        final.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.{TEMP_TAG}", suffix=".tmp", dir=final.parent))
    try:
        os.chmod(tmp, 0o777 & ~current_umask())
        yield tmp
        check_interrupted()
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    if final.exists():
        old = final.with_name(f".{final.name}.{TEMP_TAG}{secrets.token_hex(4)}.old")
        os.replace(final, old)
        os.replace(tmp, final)
        if keep_hidden and old.is_dir() and not old.is_symlink():
            for e in os.scandir(old):
                if e.name.startswith(".") and not is_temporary(e.name) and not os.path.lexists(final / e.name):
                    os.replace(e.path, final / e.name)
        _remove(old)
    else:
        os.replace(tmp, final)


def remove_temporaries(trees: Iterable[Path], *, entries_of: Iterable[Path] = (),
                       keep_out: Iterable[Path] = ()) -> list[Path]:
    """Remove the temporaries a killed sagebench process left: anywhere under `trees`, and directly in each
    directory of `entries_of` (not below). Never looks inside a directory of `keep_out` (input scenes) nor
    removes one that holds such a directory. Returns what was removed, sorted.

    Only names `is_temporary` matches are touched: a user's own `.x.old` or `.y.tmp` stays.
    """
    keep = [Path(os.path.abspath(p)) for p in keep_out]
    removed: list[Path] = []

    def kept(path: Path) -> bool:
        return any(k == path or k in path.parents for k in keep)

    def visit(d: Path, deep: bool) -> None:
        try:
            entries = sorted(os.scandir(d), key=lambda e: e.name)
        except (FileNotFoundError, NotADirectoryError):
            return
        for e in entries:
            path = Path(os.path.abspath(e.path))
            if kept(path):
                continue
            is_dir = e.is_dir(follow_symlinks=False)
            if is_temporary(e.name) and not any(path in k.parents for k in keep):
                _remove(path)
                removed.append(path)
            elif is_dir and deep:
                visit(path, deep)

    for tree in trees:
        if not kept(Path(os.path.abspath(tree))):
            visit(Path(tree), deep=True)
    for d in entries_of:
        visit(Path(d), deep=False)
    return sorted(removed)


def _remove(path: Path) -> None:
    """Remove a file, link or directory tree of sagebench's own (a temporary or a replaced output)."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


def listed_files(index: Path, key: str) -> set[str]:
    """The files an earlier output's index (a JSON object) lists under `key` (a list of names, or an object whose
    values are names), relative to the index's folder: those `remove_unlisted` may remove. A name that is absolute,
    leaves the folder or has a hidden part is left out; an unreadable index lists nothing."""
    try:
        listed = json.loads(Path(index).read_text(encoding="utf-8")).get(key, [])
    except (OSError, ValueError, AttributeError):
        return set()
    names = listed.values() if isinstance(listed, dict) else listed if isinstance(listed, list) else []
    return {n for n in names if isinstance(n, str) and n and not n.startswith("/") and "\\" not in n
            and not any(part in ("", "..") or part.startswith(".") for part in n.split("/"))}


def remove_unlisted(folder: Path, earlier: Iterable[str], now: Iterable[str]) -> None:
    """Remove the files of an earlier output in `folder` (`earlier`, from `listed_files`) that the new one (`now`)
    does not have, and the folders that leaves empty: a folder written again shows one output, never a mix."""
    folder = Path(folder)
    for name in sorted(set(earlier) - set(now), reverse=True):
        path = folder / name
        if path.is_file() and not path.is_symlink():
            path.unlink()
        for parent in path.parents:
            if parent == folder or folder not in parent.parents:
                break
            with contextlib.suppress(OSError):
                parent.rmdir()
