"""One writer per run directory: an exclusive flock on RUN/.sagebench.lock, taken by every command that writes there.

The kernel drops a flock when its holder exits in any way (kill -9 included), so a crash never leaves a
stale lock to clear by hand. The file stays after a command that succeeded: unlinking it would let a waiting
process lock an inode nobody else can see (a process that opened it just before is told to try again, as the
name then no longer leads to the inode it locked). A command that fails removes the lock file if it created it.

The file is opened relative to the run directory without following a link (O_NOFOLLOW), and must be a
regular file of the user running sagebench with no other hard link: a link or a hard link planted there
would otherwise have the pid written over whatever it points to.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import stat
from collections.abc import Iterator
from pathlib import Path

from sagebench.errors import OutputError, SagebenchError
from sagebench.run_layout import LOCK

_NOFOLLOW = os.O_RDWR | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC  # O_NONBLOCK: a FIFO must not block the open


class RunLockedError(SagebenchError):
    """Another process holds the run directory's lock."""


@contextlib.contextmanager
def run_lock(run_dir: Path) -> Iterator[Path]:
    """Hold RUN_DIR's lock for the body; RunLockedError (one line, naming the holder's pid) if it is held, and an
    OutputError naming the file when RUN_DIR/.sagebench.lock is not sagebench's (a link, not a regular file,
    another user's, hard-linked elsewhere)."""
    path = Path(run_dir) / LOCK
    dir_fd = _open_dir(Path(run_dir))
    try:
        fd, created = _take(dir_fd, path, run_dir)
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode("ascii"), 0)
            yield path
        except BaseException:
            if created:  # a failed command leaves the directory as it found it
                with contextlib.suppress(OSError):
                    os.unlink(LOCK, dir_fd=dir_fd)
            raise
        finally:
            os.close(fd)
    finally:
        os.close(dir_fd)


def _open_dir(run_dir: Path) -> int:
    try:
        return os.open(run_dir, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    except OSError as err:
        raise OutputError(f"cannot open the run directory: {err.strerror or err}", path=run_dir) from None


def _take(dir_fd: int, path: Path, run_dir: Path) -> tuple[int, bool]:
    """(fd holding the flock, whether this call created the file). Retried when the name was unlinked (by a
    holder that failed) between our open and our flock."""
    for _ in range(5):
        fd, created = _open_lock(dir_fd, path)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode("ascii", "replace").strip() or "unknown"
            os.close(fd)
            raise RunLockedError(f"another sagebench command (pid {holder}) is writing this run directory; wait "
                                 "for it to end or choose another", path=run_dir) from None
        now = _lstat(dir_fd)
        mine = os.fstat(fd)
        if now is not None and (now.st_dev, now.st_ino) == (mine.st_dev, mine.st_ino):
            return fd, created
        os.close(fd)
    raise RunLockedError("the lock file keeps being replaced by another process; try again", path=path)


def _open_lock(dir_fd: int, path: Path) -> tuple[int, bool]:
    """Open (creating it when absent) the lock file without following a link, and check that it is ours."""
    try:
        return os.open(LOCK, _NOFOLLOW | os.O_CREAT | os.O_EXCL, 0o666, dir_fd=dir_fd), True
    except FileExistsError:
        pass
    except OSError as err:
        raise OutputError(f"cannot create the run lock: {err.strerror or err}", path=path) from None
    before = _lstat(dir_fd)
    if before is not None and not stat.S_ISREG(before.st_mode):
        raise _not_ours(path, "a link" if stat.S_ISLNK(before.st_mode) else "not a regular file")
    try:
        fd = os.open(LOCK, _NOFOLLOW, dir_fd=dir_fd)
    except OSError as err:
        raise OutputError(f"cannot open the run lock: {err.strerror or err}", path=path) from None
    st = os.fstat(fd)
    problem = ("not a regular file" if not stat.S_ISREG(st.st_mode)
               else f"owned by uid {st.st_uid}, not by you (uid {os.geteuid()})" if st.st_uid != os.geteuid()
               else f"hard-linked elsewhere ({st.st_nlink} links)" if st.st_nlink != 1 else None)
    if problem is not None:
        os.close(fd)
        raise _not_ours(path, problem)
    return fd, False


def _lstat(dir_fd: int) -> os.stat_result | None:
    try:
        return os.stat(LOCK, dir_fd=dir_fd, follow_symlinks=False)
    except FileNotFoundError:
        return None


def _not_ours(path: Path, problem: str) -> OutputError:
    return OutputError(f"not sagebench's lock file ({problem}); nothing was written: remove it and run again",
                       path=path)
