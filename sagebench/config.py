"""Settings shared by several stages, with their defaults in one place."""

from __future__ import annotations

import types
from collections.abc import Mapping
from typing import Literal, TypeVar, Union, get_args, get_origin

from pydantic import BaseModel, ConfigDict, Field, ValidationError, ValidationInfo, field_validator

from sagebench.errors import ConfigError, first_error


class AgentConfig(BaseModel):
    """The robot's body, declared here and nowhere else (metres above the floor): a cylinder of `radius` from
    `clearance` up to `height`. That span is the band whose geometry blocks: build-scene's occupancy, export-usd's
    collider band check and the replay's agent all use it. build-scene builds a run's maps for it and records it in
    semantic_map.json; every later stage takes it from there."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    radius: float = Field(default=0.20, gt=0, description="Cylinder radius, m; the navigable map is inflated by it.")
    clearance: float = Field(default=0.05, ge=0, description=(
        "Cylinder bottom above the floor, m: the bottom of the blocking band (a rug or a threshold below it is "
        "driven over)."))
    height: float = Field(default=1.2, gt=0,
                          description="Cylinder top above the floor, m: the top of the blocking band.")

    @property
    def band(self) -> tuple[float, float]:
        """(bottom, top) of the blocking band above the floor, m: the body's span."""
        return self.clearance, self.height

    @field_validator("height")
    @classmethod
    def _above_clearance(cls, height: float, info: ValidationInfo) -> float:
        clearance = info.data.get("clearance")
        if clearance is not None and height <= clearance:
            raise ValueError(f"{height} must be above the band's bottom, clearance ({clearance})")
        return height


class CameraConfig(BaseModel):
    """The agent's camera: what each stage that renders views sees through (metres, degrees)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    height: float = Field(default=1.2, gt=0, description="Camera above the floor, m.")
    hfov_deg: float = Field(default=90.0, gt=0, lt=180, description="Horizontal field of view, degrees.")


M = TypeVar("M", bound=BaseModel)


def from_options(model: type[M], given: Mapping[str, object], options: Mapping[str, str]) -> M:
    """Validate a stage's settings from command options (None = keep the default).

    given: the settings as nested field names; options: each command option and the dotted field path it
    sets ({"--prune": "splats.prune"}), so a bad value is one ConfigError naming the option the user typed.
    """
    try:
        return model.model_validate(_drop_none(given))
    except ValidationError as err:
        loc, msg, _ = first_error(err)
        option = {path: opt for opt, path in options.items()}.get(loc or "", loc)
        raise ConfigError(msg, field=option or None) from None


def option_defaults(model: type[BaseModel], options: Mapping[str, str]) -> dict[str, object]:
    """Each option's default: the default of the model field it sets (options as in `from_options`), so
    help text and README show the model's defaults and nothing restates them."""
    defaults = {}
    for option, path in options.items():
        first, *rest = path.split(".")
        value = model.model_fields[first].get_default(call_default_factory=True)
        for part in rest:
            value = getattr(value, part)
        defaults[option] = value
    return defaults


def option_choices(model: type[BaseModel], options: Mapping[str, str], option: str) -> tuple[str, ...]:
    """The values an option may take where the model field it sets is a Literal (shell completion offers
    them), else (); options as in `from_options`."""
    annotation: object = model
    for part in options[option].split("."):
        annotation = _model_of(annotation).model_fields[part].annotation
    return tuple(str(v) for v in _literal_values(annotation))


def _model_of(annotation: object) -> type[BaseModel]:
    """The BaseModel class of a field annotation (`X` or `X | None`)."""
    for t in (annotation, *get_args(annotation)):
        if isinstance(t, type) and issubclass(t, BaseModel):
            return t
    raise TypeError(f"{annotation!r} is not a settings model")


def _literal_values(annotation: object) -> list[object]:
    if get_origin(annotation) is Literal:
        return list(get_args(annotation))
    if get_origin(annotation) in (Union, types.UnionType):
        return [v for arg in get_args(annotation) for v in _literal_values(arg)]
    return []


def _drop_none(given: Mapping[str, object]) -> dict[str, object]:
    return {k: _drop_none(v) if isinstance(v, Mapping) else v for k, v in given.items() if v is not None}
