"""One error hierarchy: every bad input becomes one line for the user and exit status 2."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pydantic import ValidationError


class SagebenchError(Exception):
    """Bad input or an impossible request; `str(err)` is the one line the CLI prints."""

    exit_code = 2

    def __init__(self, message: str, *, path: Path | str | None = None, field: str | None = None):
        self.path = None if path is None else str(path)
        self.field = field
        # one line, whatever a library put in its message (MuJoCo and GEOS write several)
        message = "; ".join(line.strip() for line in str(message).splitlines() if line.strip())
        self.detail = message
        parts = [p for p in (self.path, field) if p]
        super().__init__(": ".join([*parts, message]))


class SceneError(SagebenchError):
    """scene.json is malformed or breaks a rule of the input format."""


class MeshError(SceneError):
    """A mesh is missing, unreadable, outside the scene directory, empty or non-finite."""


class ConfigError(SagebenchError):
    """A command option or config file value is out of range."""


class OutputError(SagebenchError):
    """An output cannot be written there: a file where a directory goes (or the reverse), no permission, a full disk."""


class DataError(SagebenchError):
    """A file sagebench wrote earlier (map, shard, PLY) is missing or malformed."""


class ColliderError(SagebenchError):
    """Colliders could not be made as asked: a method past its safety limit, or a collider that would cover free
    floor (a doorway) that its object leaves open."""


class ServiceError(SagebenchError):
    """A service the command relies on (the LLM server) did not deliver; exit status 1, nothing written."""

    exit_code = 1


class Interrupted(SagebenchError):
    """Ctrl-C: the work in progress was dropped, not written; exit status 130 as for SIGINT."""

    exit_code = 130


def first_error(err: ValidationError) -> tuple[str | None, str, dict[str, Any]]:
    """The first problem pydantic found: (field path such as 'objects[3].kind' or None, message, raw entry)."""
    e = err.errors(include_url=False)[0]
    return field_path(e["loc"]) or None, e["msg"].removeprefix("Value error, "), e


def field_path(loc: Sequence[str | int]) -> str:
    """('objects', 3, 'kind') -> 'objects[3].kind'."""
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out
