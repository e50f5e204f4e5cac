"""One writer per run directory (and per results file): an exclusive flock on a lock file, RUN/.sagebench.lock for
a run, taken by every command that writes there.

The kernel drops a flock when its holder exits in any way (kill -9 included), so a crash never leaves a
stale lock to clear by hand. A run's lock file stays after a command that succeeded (a command that fails removes
it if it created it); a results file's lock is removed when its holder ends. Every holder checks, once it has the
flock, that the name still leads to the inode it locked, and tries again when not: a holder may unlink the name
while it holds it, and the next one then locks a fresh file.

The file is opened relative to its directory without following a link (O_NOFOLLOW), and must be a regular
file of the user running sagebench; the pid is written only into a file with no other hard link, so a link or
a hard link planted there never has it written over whatever it points to. A lock file with other hard links
that holds nothing but a pid (a copy made with `cp -al` shares the original's) is never written: once its flock
shows that nobody holds it, its name is unlinked (the other links keep the inode) and a fresh file takes its place.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import re
import stat
from collections.abc import Iterator
from pathlib import Path

from sagebench.errors import OutputError, SagebenchError
from sagebench.run_layout import LOCK

_NOFOLLOW = os.O_RDWR | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC  # O_NONBLOCK: a FIFO must not block the open
_PID_LINE = re.compile(rb"\d{0,20}\n?")  # all a sagebench lock file ever holds


class RunLockedError(SagebenchError):
    """Another process holds the run directory's lock."""


@contextlib.contextmanager
def run_lock(run_dir: Path) -> Iterator[Path]:
    """Hold RUN_DIR's lock for the body; RunLockedError (one line, naming the holder's pid) if it is held, and an
    OutputError naming the file when RUN_DIR/.sagebench.lock is not sagebench's (a link, not a regular file,
    another user's, hard-linked to a file that is not a lock)."""
    with _held(Path(run_dir), LOCK, "run directory", keep=True) as path:
        yield path


def results_lock_name(results: Path) -> str:
    return f".{Path(results).name}.sagebench.lock"


@contextlib.contextmanager
def results_lock(results: Path) -> Iterator[Path]:
    """Hold the lock of one results file (a rollout's predictions) for the body: `.NAME.sagebench.lock` beside
    it, removed when the body ends; refused as run_lock is."""
    results = Path(results)
    with _held(results.parent, results_lock_name(results), "results file", keep=False, subject=results) as path:
        yield path


@contextlib.contextmanager
def _held(folder: Path, name: str, what: str, *, keep: bool, subject: Path | None = None) -> Iterator[Path]:
    path = folder / name
    dir_fd = _open_dir(folder)
    try:
        fd, created = _take(dir_fd, name, path, what, subject or folder)
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode("ascii"), 0)
            yield path
            if not keep:  # still held: a process waiting on this inode finds the name gone and tries again
                _unlink(dir_fd, name)
        except BaseException:
            if created or not keep:  # a failed command leaves the directory as it found it
                _unlink(dir_fd, name)
            raise
        finally:
            os.close(fd)
    finally:
        os.close(dir_fd)


def _unlink(dir_fd: int, name: str) -> None:
    with contextlib.suppress(OSError):
        os.unlink(name, dir_fd=dir_fd)


def _open_dir(run_dir: Path) -> int:
    try:
        return os.open(run_dir, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    except OSError as err:
        raise OutputError(f"cannot open the run directory: {err.strerror or err}", path=run_dir) from None


def _take(dir_fd: int, name: str, path: Path, what: str, subject: Path) -> tuple[int, bool]:
    """(fd holding the flock, whether this call created the file). Retried when the name was unlinked (by a
    holder that failed or ended, or in place of a shared stale lock) between our open and our flock."""
    for _ in range(5):
        fd, created = _open_lock(dir_fd, name, path)
        _flock(fd, what, subject)
        now = _lstat(dir_fd, name)
        mine = os.fstat(fd)
        if now is not None and (now.st_dev, now.st_ino) == (mine.st_dev, mine.st_ino):
            if mine.st_nlink == 1:
                return fd, created
            _unlink(dir_fd, name)  # a stale lock shared with a copy (checked in _open_lock), held by nobody
        os.close(fd)
    raise RunLockedError("the lock file keeps being replaced by another process; try again", path=path)


def _flock(fd: int, what: str, subject: Path) -> None:
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = os.pread(fd, 32, 0).decode("ascii", "replace").strip() or "unknown"
        os.close(fd)
        raise RunLockedError(f"another sagebench command (pid {holder}) is writing this {what}; wait for it to end "
                             "or choose another", path=subject) from None


def _open_lock(dir_fd: int, name: str, path: Path) -> tuple[int, bool]:
    """Open (creating it when absent) the lock file without following a link, and check that it is ours."""
    try:
        return os.open(name, _NOFOLLOW | os.O_CREAT | os.O_EXCL, 0o666, dir_fd=dir_fd), True
    except FileExistsError:
        pass
    except OSError as err:
        raise OutputError(f"cannot create the run lock: {err.strerror or err}", path=path) from None
    before = _lstat(dir_fd, name)
    if before is not None and not stat.S_ISREG(before.st_mode):
        raise _not_ours(path, "a link" if stat.S_ISLNK(before.st_mode) else "not a regular file")
    try:
        fd = os.open(name, _NOFOLLOW, dir_fd=dir_fd)
    except OSError as err:
        raise OutputError(f"cannot open the run lock: {err.strerror or err}", path=path) from None
    st = os.fstat(fd)
    problem = ("not a regular file" if not stat.S_ISREG(st.st_mode)
               else f"owned by uid {st.st_uid}, not by you (uid {os.geteuid()})" if st.st_uid != os.geteuid()
               else f"hard-linked elsewhere ({st.st_nlink} links)" if st.st_nlink != 1 and not _a_lock(fd, st)
               else None)
    if problem is not None:
        os.close(fd)
        raise _not_ours(path, problem)
    return fd, False


def _a_lock(fd: int, st: os.stat_result) -> bool:
    """Whether the open file holds nothing but what a sagebench lock holds (a pid line)."""
    return st.st_size <= 21 and _PID_LINE.fullmatch(os.pread(fd, 32, 0)) is not None


def _lstat(dir_fd: int, name: str) -> os.stat_result | None:
    try:
        return os.stat(name, dir_fd=dir_fd, follow_symlinks=False)
    except FileNotFoundError:
        return None


def _not_ours(path: Path, problem: str) -> OutputError:
    return OutputError(f"not sagebench's lock file ({problem}); nothing was written: remove it and run again",
                       path=path)
