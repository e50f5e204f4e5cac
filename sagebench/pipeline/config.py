"""Reading the TOML run config of `sagebench run` (its model: sagebench/settings/run.py) and finding its scenes."""

from __future__ import annotations

import glob
import tomllib
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from sagebench.errors import ConfigError, first_error
from sagebench.settings.run import RunConfig


def load_run_config(path: Path, **overrides: Any) -> RunConfig:
    """Read and validate a TOML run config; `overrides` (not None) replace top-level keys."""
    try:
        raw = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as err:
        raise ConfigError(f"cannot read: {err.strerror}", path=path) from None
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"malformed TOML: {err}", path=path) from None
    except RecursionError:
        raise ConfigError("malformed TOML: nested too deeply", path=path) from None
    except UnicodeDecodeError as err:
        raise ConfigError(f"cannot read: not UTF-8 text ({err.reason})", path=path) from None
    except ValueError as err:  # an integer of more than sys.get_int_max_str_digits() digits
        raise ConfigError(f"malformed TOML: {str(err).split(';')[0]}", path=path) from None
    raw |= {k: v for k, v in overrides.items() if v is not None}
    base = Path(path).resolve().parent
    seed = raw.get("seed")
    if seed is not None:
        for stage in ("build_scene", "gen_trajectories", "validate"):
            table = raw.setdefault(stage, {})
            if isinstance(table, dict):
                table.setdefault("seed", seed)
    try:
        config = RunConfig.model_validate(raw)
    except ValidationError as err:
        loc, msg, _ = first_error(err)
        raise ConfigError(msg, path=path, field=loc) from None
    return config.model_copy(update={
        "out": _under(base, config.out),
        "cache_dir": None if config.cache_dir is None else _under(base, config.cache_dir),
        "scenes": config.scenes,
    })


def resolve_scenes(config: RunConfig, config_path: Path) -> list[Path]:
    """The scene directories the config names, sorted and de-duplicated; a pattern matching nothing is an error."""
    base = Path(config_path).resolve().parent
    found: set[Path] = set()
    for i, pattern in enumerate(config.scenes):
        full = str(_under(base, Path(pattern)))
        matches = [Path(m) for m in glob.glob(full)] if glob.has_magic(full) else [Path(full)]
        dirs = [m for m in matches if m.is_dir()]
        if not dirs:
            raise ConfigError(f"{pattern!r} matches no scene directory", path=config_path, field=f"scenes[{i}]")
        found.update(d.resolve() for d in dirs)
    return sorted(found)


def _under(base: Path, p: Path) -> Path:
    return p if p.is_absolute() else base / p
