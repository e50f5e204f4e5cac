"""Process-wide output settings (--quiet, --debug) and the progress bar every long stage uses."""

from __future__ import annotations

import sys
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import TypeVar

T = TypeVar("T")


@dataclass
class Settings:
    quiet: bool = False
    debug: bool = False


SETTINGS = Settings()


def track(items: Iterable[T], description: str, total: int | None = None) -> Iterator[T]:
    """Iterate with a rich progress bar on a terminal; plain iteration when quiet or not a TTY."""
    if SETTINGS.quiet or not sys.stderr.isatty():
        yield from items
        return
    from rich.progress import track as rich_track

    yield from rich_track(items, description=description, total=total, transient=True)


def info(message: str) -> None:
    """A line for people on stderr, hidden by --quiet."""
    if not SETTINGS.quiet:
        print(message, file=sys.stderr)


def warn(message: str) -> None:
    """A warning always reaches stderr, even with --quiet."""
    print(f"warning: {message}", file=sys.stderr)
