"""Process-wide output settings (--quiet, --debug), the progress bar every long stage uses, and warnings
(printed at once, or collected while a pipeline task runs so the driver prints them: a Ray worker's
stderr never reaches the terminal)."""

from __future__ import annotations

import contextlib
import sys
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


def track(items: Iterable[T], description: str, total: int | None = None) -> Iterator[T]:
    """Iterate with a rich progress bar on a terminal; plain iteration when quiet or not a TTY."""
    if SETTINGS.quiet or not sys.stderr.isatty():
        yield from items
        return
    from rich.progress import track as rich_track

    yield from rich_track(items, description=description, total=total, transient=True)


@contextmanager
def progress(total: int, description: str) -> Iterator[Callable[[int, str], None]]:
    """A bar the caller advances: `update(completed, status)` (status: a short text shown after the bar, such
    as a rate); does nothing when quiet or not a TTY."""
    if SETTINGS.quiet or not sys.stderr.isatty():
        yield lambda completed, status: None
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
