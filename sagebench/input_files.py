"""Reading an input file: refused by its type before it is opened, and JSON parsed within Python's limits.

A FIFO as an input would block the read forever and a device such as /dev/zero never end it, so anything but
a regular file (or, for a command's path arguments, a directory) is refused by `os.stat` before it is opened
(and the opened file is checked again, so a file swapped for a FIFO in between cannot block either).
JSON nesting deeper than Python's recursion limit and integers of more than `sys.get_int_max_str_digits()`
digits are refused in one line, as scene.json and run.toml refuse them.
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path
from typing import Any

from sagebench.errors import DataError, SagebenchError

_SPECIAL = ((stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
            (stat.S_ISSOCK, "a socket"))


def special_kind(path: Path | str, *, mode: int | None = None) -> str | None:
    """'a FIFO', 'a character device', ... when `path` (links followed) is neither a regular file nor a directory;
    None for those, and for a path that cannot be examined (reading it then says why)."""
    if mode is None:
        try:
            mode = os.stat(path).st_mode
        except (OSError, ValueError):
            return None
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return None
    return next((what for test, what in _SPECIAL if test(mode)), "not a regular file")


def read_input(path: Path | str, error: type[SagebenchError] = DataError) -> bytes:
    """The bytes of the input file `path`; anything but a regular file, or a read that fails, is one `error`."""
    _refuse_special(path, special_kind(path), error)
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
        with os.fdopen(fd, "rb") as fh:
            _refuse_special(path, special_kind(path, mode=os.fstat(fd).st_mode), error)  # swapped since examined
            return fh.read()
    except OSError as err:
        raise error(f"cannot read: {err.strerror or err}", path=path) from None


def _refuse_special(path: Path | str, kind: str | None, error: type[SagebenchError]) -> None:
    if kind is not None:
        raise error(f"is {kind}, not a file: sagebench reads inputs from regular files only", path=path)


def loads_json(text: str | bytes, where: Path | str, error: type[SagebenchError] = DataError) -> Any:
    """JSON text parsed; malformed, too deeply nested or holding an integer too long to convert, one `error`."""
    try:
        return json.loads(text.decode("utf-8") if isinstance(text, bytes) else text)
    except json.JSONDecodeError as err:
        raise error(f"malformed JSON at line {err.lineno}, column {err.colno}: {err.msg}", path=where) from None
    except RecursionError:
        raise error("JSON nested too deeply", path=where) from None
    except UnicodeDecodeError as err:
        raise error(f"cannot read: not UTF-8 text ({err.reason})", path=where) from None
    except ValueError as err:  # an integer of more than sys.get_int_max_str_digits() digits
        raise error(f"malformed JSON: {str(err).split(';')[0]}", path=where) from None


def read_json(path: Path | str, error: type[SagebenchError] = DataError) -> Any:
    """The JSON document in the input file `path` (read_input, then loads_json)."""
    return loads_json(read_input(path, error), path, error)
