"""build-scene's settings (map grid and band, agent, Gaussians), apart from the builder (so a command line parses
them cheaply)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from sagebench.config import AgentConfig, CameraConfig
from sagebench.splats.config import SplatConfig


class BuildSceneConfig(BaseModel):
    """Settings of build-scene; the CLI maps its options onto these fields. The blocking band is the agent's body
    (AgentConfig: clearance .. height above the floor)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    resolution: float = Field(default=0.05, gt=0, le=1.0, description="Grid cell side, m.")
    sample_density: float = Field(default=400.0, gt=0, description="Footprint surface samples per m^2.")
    wall_gap: float = Field(
        default=0.3, ge=0, description="Room floor polygons closer than this join across the wall between them, m."
    )
    seed: int = Field(default=0, ge=0, description="Seed of the footprint surface and Gaussian sampling.")
    agent: AgentConfig = AgentConfig()
    camera: CameraConfig = CameraConfig()
    splats: SplatConfig = SplatConfig()
