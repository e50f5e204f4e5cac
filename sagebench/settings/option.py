"""How a setting becomes a command-line option: the marker its field carries, the options a command's settings
model declares, and the model read back from the options given.

A field declares its option once, beside its default and description: `Annotated[float, Option("--goal-radius")]`.
A nested settings field marked `EXPAND` lends its fields' options to the command (build-scene's `agent` gives
--agent-radius, --band-min, --band-max); a nested field without it keeps its settings out of the command line
(build-scene's `camera`). The CLI (sagebench/cli_settings.py) makes each option from this, with the field's
description as its help and its default shown from the field.
"""

from __future__ import annotations

import functools
import types
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Literal, TypeVar, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined

from sagebench.errors import ConfigError, first_error


@dataclass(frozen=True)
class Option:
    """Marks a settings field as the command-line option `name` (in `Annotated[type, Option(name)]`).

    required: the command needs it even though the field has a default (baseline's --agent); parse: turns the
    option's text into the field's value (--obs rgb,depth); values: what shell completion offers for a free
    string (a Literal field offers its own values)."""

    name: str
    required: bool = False
    parse: Callable[[str], object] | None = None
    values: tuple[str, ...] = ()


class _Expand:
    """Marks a nested settings field whose fields' options are the command's too."""

    def __repr__(self) -> str:
        return "EXPAND"


EXPAND = _Expand()


@dataclass(frozen=True)
class Setting:
    """One option of a command: the field it sets (its dotted path in the command's model) and that field."""

    option: Option
    path: str
    field: FieldInfo
    default: object  # the field's default within the command's model (a nested model's default can differ)

    @property
    def name(self) -> str:
        return self.option.name

    @property
    def description(self) -> str:
        return self.field.description or ""

    @property
    def kind(self) -> object:
        """The field's type without None: int, float, str, Path, bool, a Literal or tuple[str, ...]."""
        args = [a for a in get_args(self.field.annotation) if a is not type(None)]
        union = get_origin(self.field.annotation) in (Union, types.UnionType)
        return args[0] if union and len(args) == 1 else self.field.annotation

    @property
    def choices(self) -> tuple[str, ...]:
        """What shell completion offers: the Literal's values, else the option's `values`."""
        return tuple(str(v) for v in _literal_values(self.field.annotation)) or self.option.values


@functools.cache
def settings_of(model: type[BaseModel]) -> tuple[Setting, ...]:
    """Every option of a command whose settings are `model`, in field order (nested ones where they are)."""
    return tuple(_settings(model, None, ""))


def _settings(model: type[BaseModel], defaults: BaseModel | None, prefix: str) -> list[Setting]:
    found = []
    for name, field in model.model_fields.items():
        value = field.get_default(call_default_factory=True) if defaults is None else getattr(defaults, name)
        value = None if value is PydanticUndefined else value  # a required field (the run config's `out`)
        markers = field.metadata
        if any(m is EXPAND for m in markers):
            found += _settings(type(value), value, f"{prefix}{name}.")
        found += [Setting(m, f"{prefix}{name}", field, value) for m in markers if isinstance(m, Option)]
    return found


M = TypeVar("M", bound=BaseModel)


def from_options(model: type[M], given: Mapping[str, object], base: Mapping[str, object] | None = None) -> M:
    """The settings from the options given ({"--band-max": 1.8}; None = keep the default), over `base`
    (nested field values, e.g. a preset's), validated: a bad value is one ConfigError naming the option typed."""
    try:
        return model.model_validate(fields_given(model, given, base))
    except ValidationError as err:
        loc, msg, _ = first_error(err)
        option = next((s.name for s in settings_of(model) if s.path == loc), loc)
        raise ConfigError(msg, field=option) from None


def fields_given(model: type[BaseModel], given: Mapping[str, object],
                 base: Mapping[str, object] | None = None) -> dict[str, object]:
    """The options given as the nested field values they set, over `base` (not validated)."""
    paths = {s.name: s.path for s in settings_of(model)}
    values: dict = _copy(base or {})
    for option, value in parsed(model, given).items():
        if value is None:
            continue
        *parents, leaf = paths[option].split(".")
        table = values
        for part in parents:
            table = table.setdefault(part, {})
        table[leaf] = value
    return values


def parsed(model: type[BaseModel], given: Mapping[str, object]) -> dict[str, object]:
    """The options given with each option's text parsed where its field says how (--obs "rgb,depth" -> ("rgb",
    "depth")); a value already parsed is kept."""
    parse = {s.name: s.option.parse for s in settings_of(model) if s.option.parse is not None}
    return {o: parse[o](v) if o in parse and isinstance(v, str) else v for o, v in given.items()}


def _copy(tables: Mapping[str, object]) -> dict:
    return {k: _copy(v) if isinstance(v, Mapping) else v for k, v in tables.items()}


def _literal_values(annotation: object) -> list[object]:
    if get_origin(annotation) is Literal:
        return list(get_args(annotation))
    if get_origin(annotation) in (Union, types.UnionType):
        return [v for arg in get_args(annotation) for v in _literal_values(arg)]
    return []
