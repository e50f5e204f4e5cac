"""The settings of a scene's Gaussians, apart from the code that makes them (so a command line parses them cheaply)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field


class SplatConfig(BaseModel):
    """How a scene gets its Gaussians (densities per square metre of surface, both sides of thin parts)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    object_density: float = Field(default=900.0, gt=0, description="Gaussians per m^2 on objects, doors, windows.")
    structure_density: float = Field(default=300.0, gt=0, description="Gaussians per m^2 on walls, floors, ceilings.")
    scale_factor: float = Field(default=0.7, gt=0, description="In-plane sigma as a multiple of the sample spacing.")
    thickness_ratio: float = Field(default=0.1, gt=0, le=1, description="Normal sigma / in-plane sigma.")
    opacity: float = Field(default=0.95, gt=0, lt=1, description="Opacity of sampled Gaussians.")
    shading: float = Field(default=0.35, ge=0, le=1, description="Strength of the baked soft light (0 = flat colour).")
    assign_tolerance: float = Field(default=0.05, gt=0, description="Trained Gaussians farther from every surface, m, get id 0.")
    cull_unseen: bool = Field(default=True, description="Skip wall/floor/ceiling faces that face away from every room.")
    prune: float = Field(default=0.0, ge=0, lt=1, description="Fraction of Gaussians to drop by contribution.")
    prune_views: int = Field(default=32, ge=1, description="Scoring views (and a quarter as many held out).")
    prune_width: int = Field(default=320, ge=16, description="Scoring view width, px (height 3/4 of it).")
