"""Settings shared by several stages, with their defaults in one place."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TypeVar

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from sagebench.errors import ConfigError, first_error


class AgentConfig(BaseModel):
    """The robot every map, path and replay is made for (metres, degrees)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    radius: float = Field(default=0.20, gt=0, description="Cylinder radius, m.")
    height: float = Field(default=1.2, gt=0, description="Cylinder height, m.")
    camera_height: float = Field(default=1.2, gt=0, description="Camera above the floor, m.")
    hfov_deg: float = Field(default=90.0, gt=0, lt=180, description="Horizontal field of view, degrees.")


M = TypeVar("M", bound=BaseModel)


def from_options(model: type[M], given: Mapping[str, object], option_of: Callable[[str], str | None] = str) -> M:
    """Validate a stage's settings from command options (None = keep the default).

    A bad value is one ConfigError naming the option: `option_of` maps the failing field's dotted path
    ("coacd.threshold") to the option the user typed.
    """
    try:
        return model.model_validate(_drop_none(given))
    except ValidationError as err:
        loc, msg, _ = first_error(err)
        raise ConfigError(msg, field=(option_of(loc) if loc else None) or None) from None


def _drop_none(given: Mapping[str, object]) -> dict[str, object]:
    return {k: _drop_none(v) if isinstance(v, Mapping) else v for k, v in given.items() if v is not None}
