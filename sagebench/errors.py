"""One error hierarchy: every bad input becomes one line for the user and exit status 2."""

from __future__ import annotations

from pathlib import Path


class SagebenchError(Exception):
    """Bad input or an impossible request; `str(err)` is the one line the CLI prints."""

    exit_code = 2

    def __init__(self, message: str, *, path: Path | str | None = None, field: str | None = None):
        self.path = None if path is None else str(path)
        self.field = field
        self.detail = message
        parts = [p for p in (self.path, field) if p]
        super().__init__(": ".join([*parts, message]))


class SceneError(SagebenchError):
    """scene.json is malformed or breaks a rule of the input format."""


class MeshError(SceneError):
    """A mesh is missing, unreadable, outside the scene directory, empty or non-finite."""


class ConfigError(SagebenchError):
    """A command option or config file value is out of range."""


class DataError(SagebenchError):
    """A file sagebench wrote earlier (map, shard, PLY) is missing or malformed."""
