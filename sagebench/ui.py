"""Process-wide output settings (--quiet, --debug), the progress every long stage shows, and warnings
(printed at once, or collected while a pipeline task runs so the driver prints them: a Ray worker's
stderr never reaches the terminal).

Progress is a rich bar on a terminal; off one (a log, CI, a pipe) it is a plain line on stderr at most every
PROGRESS_EVERY_S seconds, so a stage that runs for a while still says where it is; --quiet hides both.
"""

from __future__ import annotations

import contextlib
import importlib.machinery
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import TypeVar

T = TypeVar("T")


@dataclass
class Settings:
    quiet: bool = False
    debug: bool = False
    collected: list[str] | None = field(default=None, repr=False)  # warnings of the task running, if collecting


SETTINGS = Settings()


def worker_settings() -> Settings:
    """The driver's --quiet and --debug, for the initializer of a worker process (`adopt`)."""
    return Settings(quiet=SETTINGS.quiet, debug=SETTINGS.debug)


def adopt(settings: Settings) -> None:
    """In a worker process: the driver's settings (`worker_settings`). A spawned or fork-server process starts
    from the defaults, and its progress lines ignored --quiet."""
    SETTINGS.quiet, SETTINGS.debug = settings.quiet, settings.debug


PROGRESS_EVERY_S = 5.0  # off a terminal, a long stage prints where it is at most this often
_INTERRUPTED = threading.Event()


@contextmanager
def interrupts_noted() -> Iterator[None]:
    """Ctrl-C raises KeyboardInterrupt as always, and is also noted, so that `check_interrupted` raises it again
    where a library swallowed it (trimesh imports its optional parts under `except BaseException`). Installed
    only over Python's own handler (a job started with SIGINT ignored keeps ignoring it); inside another
    `interrupts_noted` (the console entry's, which covers the CLI's own imports) it keeps what that one noted."""
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        yield
        return
    _INTERRUPTED.clear()

    def note(signum, frame):  # noqa: ANN001 - signal's handler signature
        _INTERRUPTED.set()
        raise KeyboardInterrupt

    previous = sys.unraisablehook

    def quiet(unraisable) -> None:  # noqa: ANN001 - sys.unraisablehook's signature
        if not isinstance(unraisable.exc_value, KeyboardInterrupt):  # Ctrl-C raised in a callback: noted already
            previous(unraisable)

    signal.signal(signal.SIGINT, note)
    sys.unraisablehook = quiet
    finder = _UsdImportsFinishFirst()
    sys.meta_path.insert(0, finder)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        sys.unraisablehook = previous
        sys.meta_path.remove(finder)


class _UsdImportsFinishFirst:
    """USD loads the Python modules of the libraries a pxr module needs under a catch-all that prints a Ctrl-C
    landing there as a 'Warning' with its traceback, and goes on half-loaded; while a pxr module imports, Ctrl-C
    is only noted, and raised when the outermost pxr import ends."""

    def __init__(self) -> None:
        self.depth = 0
        self.handler: Callable | None = None  # SIGINT's handler outside the outermost pxr import

    def find_spec(self, name: str, path, target=None):  # noqa: ANN001, ANN201 - importlib's MetaPathFinder hook
        if name.partition(".")[0] != "pxr" or threading.current_thread() is not threading.main_thread():
            return None
        spec = importlib.machinery.PathFinder.find_spec(name, path, target)
        if spec is not None and spec.loader is not None:
            spec.loader.exec_module = self._deferring(spec.loader.exec_module)
        return spec

    def _deferring(self, exec_module: Callable) -> Callable:
        def exec_deferred(module) -> None:  # noqa: ANN001 - a module
            if self.depth == 0:
                self.handler = signal.signal(signal.SIGINT, lambda signum, frame: _INTERRUPTED.set())
            self.depth += 1
            try:
                exec_module(module)
            finally:
                self.depth -= 1
                if self.depth == 0:
                    signal.signal(signal.SIGINT, self.handler)
            if self.depth == 0:
                check_interrupted()
        return exec_deferred


def interrupted() -> bool:
    return _INTERRUPTED.is_set()


def check_interrupted() -> None:
    """KeyboardInterrupt if Ctrl-C was pressed under `interrupts_noted`, even when the first one was swallowed;
    every atomic write calls it before it renames an output into place."""
    if interrupted():
        raise KeyboardInterrupt


def track(items: Iterable[T], description: str, total: int | None = None) -> Iterator[T]:
    """Iterate with a rich progress bar on a terminal, progress lines off one (_Lines); plain iteration when
    quiet."""
    if SETTINGS.quiet:
        yield from items
        return
    if not sys.stderr.isatty():
        lines = _Lines(description, total if total is not None else _length(items))
        for n, item in enumerate(items, 1):
            yield item
            lines.update(n)
        return
    from rich.progress import track as rich_track

    yield from rich_track(items, description=description, total=total, transient=True)


def _length(items: Iterable) -> int | None:
    try:
        return len(items)  # type: ignore[arg-type]
    except TypeError:
        return None


class _Lines:
    """`description: 12/40 in 31 s, status` on stderr when PROGRESS_EVERY_S have passed since the last line."""

    def __init__(self, description: str, total: int | None):
        self.description, self.total = description, total
        self.start = self.last = time.monotonic()

    def update(self, completed: int, status: str = "") -> None:
        now = time.monotonic()
        if now - self.last < PROGRESS_EVERY_S:
            return
        self.last = now
        of = f"/{self.total}" if self.total is not None else ""
        tail = f", {status}" if status else ""
        print(f"{self.description}: {completed}{of} in {now - self.start:.0f} s{tail}", file=sys.stderr, flush=True)


@contextmanager
def working(description: str) -> Iterator[None]:
    """A step that reports no progress of its own (a batch of MuJoCo replays): off a terminal, `description: 12 s`
    on stderr every PROGRESS_EVERY_S while it runs; nothing on a terminal or when quiet."""
    if SETTINGS.quiet or sys.stderr.isatty():
        yield
        return
    stop, start = threading.Event(), time.monotonic()

    def tick() -> None:
        while not stop.wait(PROGRESS_EVERY_S):
            print(f"{description}: {time.monotonic() - start:.0f} s", file=sys.stderr, flush=True)

    thread = threading.Thread(target=tick, name="sagebench-progress", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()


@contextmanager
def progress(total: int, description: str) -> Iterator[Callable[[int, str], None]]:
    """A bar the caller advances: `update(completed, status)` (status: a short text shown after the bar, such
    as a rate); progress lines off a terminal (_Lines), nothing when quiet."""
    if SETTINGS.quiet:
        yield lambda completed, status: None
        return
    if not sys.stderr.isatty():
        yield _Lines(description, total).update
        return
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                  TextColumn("{task.fields[status]}"), transient=True) as bar:
        task = bar.add_task(description, total=total, status="")
        yield lambda completed, status: bar.update(task, completed=completed, status=status)


def info(message: str) -> None:
    """A line for people on stderr, hidden by --quiet."""
    if not SETTINGS.quiet:
        print(message, file=sys.stderr)


def warn(message: str) -> None:
    """A warning always reaches stderr, even with --quiet (through the driver while collected)."""
    if SETTINGS.collected is not None:
        SETTINGS.collected.append(message)
    else:
        print(f"warning: {message}", file=sys.stderr)


@contextlib.contextmanager
def collect_warnings() -> Iterator[list[str]]:
    """Collect the warnings given inside the block instead of printing them (nesting is not needed)."""
    SETTINGS.collected = found = []
    try:
        yield found
    finally:
        SETTINGS.collected = None
