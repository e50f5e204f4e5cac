"""Settings shared by several stages, with their defaults in one place."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field


class AgentConfig(BaseModel):
    """The robot every map, path and replay is made for (metres, degrees)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    radius: float = Field(default=0.20, gt=0, description="Cylinder radius, m.")
    height: float = Field(default=1.2, gt=0, description="Cylinder height, m.")
    camera_height: float = Field(default=1.2, gt=0, description="Camera above the floor, m.")
    hfov_deg: float = Field(default=90.0, gt=0, lt=180, description="Horizontal field of view, degrees.")
