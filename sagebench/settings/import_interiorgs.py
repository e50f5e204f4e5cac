"""import-interiorgs' settings (defaults here, nowhere else): how an InteriorGS scene folder becomes a sagebench
scene (metres)."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from sagebench.settings.option import Option


class InteriorGSConfig(BaseModel):
    """How an InteriorGS scene folder becomes a sagebench scene (metres)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    voxel: Annotated[float, Option("--voxel")] = Field(
        default=0.04, gt=0, le=0.5, description="Voxel side of the object surfaces, m.")
    min_opacity: Annotated[float, Option("--min-opacity")] = Field(
        default=0.5, gt=0, description="Summed opacity a voxel needs to be solid.")
    max_parts: Annotated[int, Option("--max-parts")] = Field(
        default=24, ge=1, description="Convex parts per object surface at most.")
    box_margin: float = Field(
        default=0.02, ge=0,
        description="Boxes are grown by this for the test (Gaussians on an object's surface lie on its box), m.")
    structure_margin: float = Field(
        default=0.008, ge=0,
        description="Gaussians this close to a wall, floor or ceiling belong to it even inside an object's box "
                    "(less than a rug is thick), m.")
    structure_reach: float = Field(
        default=0.05, ge=0, description="Gaussians in no object box go to a structure this close, else background, m.")
    min_occupancy_iou: float = Field(
        default=0.8, ge=0, le=1,
        description="Warn when the free cells of occupancy.png and of the imported geometry agree less (IoU).")
    floater_cell: float = Field(
        default=0.05, gt=0,
        description="A Gaussian is a floater, dropped, when the 3 x 3 x 3 block of cells of this side around its own "
                    "holds at most floater_neighbours other Gaussians, m.")
    floater_neighbours: int = Field(default=2, ge=0, description="See floater_cell.")
    unlabelled_min_area: float = Field(
        default=0.04, ge=0,
        description="Geometry no label explains (background Gaussians in the agent's band, cells occupancy.png marks "
                    "occupied) becomes an unlabelled obstacle in pieces of this much floor or more, m^2.")
    max_unlabelled_area: float = Field(
        default=0.25, ge=0,
        description="Warn when the unlabelled obstacles cover more floor than this (labels and evidence disagree), m^2.")
    max_surface_noise: float = Field(
        default=0.005, ge=0,
        description="Warn when the Gaussians on walls and floor scatter more than this about their planes (robust "
                    "standard deviation): noise that widens obstacles and walls by about as much, m.")
