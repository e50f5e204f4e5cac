"""build-scene's settings (defaults here, nowhere else): the map grid, the agent's body whose span is the blocking
band, and the scene's Gaussians; run.toml's [build_scene] table."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from sagebench.settings.option import EXPAND, Option
from sagebench.settings.shared import AgentConfig, CameraConfig


class SplatConfig(BaseModel):
    """How a scene gets its Gaussians (densities per square metre of surface, both sides of thin parts)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    object_density: Annotated[float, Option("--object-density")] = Field(
        default=900.0, gt=0, description="Sampled Gaussians per m^2 on objects, doors and windows.")
    structure_density: Annotated[float, Option("--structure-density")] = Field(
        default=300.0, gt=0, description="Sampled Gaussians per m^2 on walls, floors and ceilings.")
    scale_factor: float = Field(default=0.7, gt=0, description="In-plane sigma as a multiple of the sample spacing.")
    thickness_ratio: float = Field(default=0.1, gt=0, le=1, description="Normal sigma / in-plane sigma.")
    opacity: float = Field(default=0.95, gt=0, lt=1, description="Opacity of sampled Gaussians.")
    shading: float = Field(default=0.35, ge=0, le=1, description="Strength of the baked soft light (0 = flat colour).")
    assign_tolerance: float = Field(default=0.05, gt=0, description="Trained Gaussians farther from every surface, m, get id 0.")
    cull_unseen: bool = Field(default=True, description="Skip wall/floor/ceiling faces that face away from every room.")
    prune: Annotated[float, Option("--prune")] = Field(
        default=0.0, ge=0, lt=1, description="Fraction of Gaussians to drop by blending contribution.")
    prune_views: int = Field(default=32, ge=1, description="Scoring views (and a quarter as many held out).")
    prune_width: int = Field(default=320, ge=16, description="Scoring view width, px (height 3/4 of it).")


class BuildSceneConfig(BaseModel):
    """Settings of build-scene. The blocking band is the agent's body (AgentConfig: clearance .. height above the
    floor)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    resolution: Annotated[float, Option("--resolution")] = Field(
        default=0.05, gt=0, le=1.0, description="Grid cell side, m.")
    sample_density: Annotated[float, Option("--sample-density")] = Field(
        default=400.0, gt=0, description="Footprint surface samples per m^2.")
    wall_gap: Annotated[float, Option("--wall-gap")] = Field(
        default=0.3, ge=0, description="Room floors closer than this join across the wall between them, m.")
    seed: Annotated[int, Option("--seed")] = Field(
        default=0, ge=0, description="Seed of the footprint and Gaussian sampling.")
    agent: Annotated[AgentConfig, EXPAND] = AgentConfig()
    camera: CameraConfig = CameraConfig()
    splats: Annotated[SplatConfig, EXPAND] = SplatConfig()
