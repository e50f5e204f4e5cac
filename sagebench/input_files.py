"""Reading an input file: refused by its type before it is opened, and JSON parsed within Python's limits.

A FIFO as an input would block the read forever and a device such as /dev/zero never end it, so anything but
a regular file (or, for a command's path arguments, a directory) is refused by `os.stat` before it is opened
(and the opened file is checked again, so a file swapped for a FIFO in between cannot block either).
JSON nesting deeper than Python's recursion limit and integers of more than `sys.get_int_max_str_digits()`
digits are refused in one line, as scene.json and run.toml refuse them. `read_regular` looks at a file the
same way without following a link and without an error (is the file at an output path sagebench's?).
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
    try:
        data = _read_if_regular(path, follow=True)
    except OSError as err:
        raise error(f"cannot read: {err.strerror or err}", path=path) from None
    if isinstance(data, str):
        raise error(f"is {data}, not a file: sagebench reads inputs from regular files only", path=path)
    return data


def read_regular(path: Path | str, *, limit: int | None, size: int = -1) -> bytes | None:
    """The first `size` bytes (all when -1) of `path` when it is a regular file of at most `limit` bytes (any
    size when None), else None: a link is not followed, and whatever cannot be read counts as no file. For
    looking at an output before replacing it (is it sagebench's?), where nothing there is an error."""
    try:
        data = _read_if_regular(path, follow=False, size=size, limit=limit)
    except OSError:
        return None
    return None if isinstance(data, str) else data


def _read_if_regular(path: Path | str, *, follow: bool, size: int = -1, limit: int | None = None) -> bytes | str:
    """The bytes of `path` (its first `size`), or what it is instead of a regular file of at most `limit` bytes
    ('a FIFO', 'a link', 'too large', ...): its type is checked before it is opened and again on the open file
    (swapped in between), so a FIFO never blocks the read and a device never ends it."""
    st = os.stat(path) if follow else os.lstat(path)
    kind = _not_regular(st.st_mode) or (limit is not None and st.st_size > limit and "too large")
    if kind:
        return kind
    flags = os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC | (0 if follow else os.O_NOFOLLOW)
    with os.fdopen(os.open(path, flags), "rb") as fh:
        return _not_regular(os.fstat(fh.fileno()).st_mode) or fh.read(size)


def _not_regular(mode: int) -> str | None:
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISLNK(mode):
        return "a link"
    return special_kind("", mode=mode) or "a directory"


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
