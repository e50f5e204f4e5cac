"""build-scene's settings (map grid and band, agent, Gaussians), apart from the builder (so a command line parses
them cheaply)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, model_validator

from sagebench.config import AgentConfig
from sagebench.splats.config import SplatConfig


class BuildSceneConfig(BaseModel):
    """Settings of build-scene; the CLI maps its options onto these fields."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    resolution: float = Field(default=0.05, gt=0, le=1.0, description="Grid cell side, m.")
    band_min: float = Field(default=0.05, ge=0, description="Lowest blocking height above the floor, m.")
    band_max: float = Field(default=1.2, gt=0, description="Highest blocking height above the floor, m.")
    sample_density: float = Field(default=400.0, gt=0, description="Footprint surface samples per m^2.")
    wall_gap: float = Field(
        default=0.3, ge=0, description="Room floor polygons closer than this join across the wall between them, m."
    )
    seed: int = Field(default=0, ge=0, description="Seed of the footprint surface and Gaussian sampling.")
    agent: AgentConfig = AgentConfig()
    splats: SplatConfig = SplatConfig()

    @model_validator(mode="after")
    def _band_order(self) -> BuildSceneConfig:
        if self.band_max <= self.band_min:
            raise ValueError(f"band_max ({self.band_max}) must be above band_min ({self.band_min})")
        return self
