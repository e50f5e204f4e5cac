"""export-usd's settings (defaults here, nowhere else): how concave pieces become colliders, CoACD's settings and
what is written; run.toml's [export_usd] table."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator

from sagebench.settings.option import EXPAND, Option

Mode = Literal["quality", "balanced", "fast"]


class CoacdParams(BaseModel):
    """The CoACD settings sagebench exposes; every one of them is part of the collider cache key.

    The search settings are cut from CoACD's own defaults (resolution 2000, 150 MCTS iterations of depth 3
    over 20 nodes): on the 19 pieces of the real-furniture bench scene whose hull misses the agent band, this
    took 44 CPU s against 157 s with 3 pieces over 40 s, for the same band errors (16 against 15 of them
    within 2 cm) and median surface distance (0.9 against 1.1 cm); on 15 pieces drawn from the rest, 12
    against 29 CPU s, same band errors and surface distances.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    threshold: Annotated[float, Option("--coacd-threshold")] = Field(
        default=0.05, gt=0, le=1, description="CoACD concavity threshold; smaller gives more, tighter parts.")
    max_convex_hull: Annotated[int, Option("--coacd-max-hulls")] = Field(
        default=-1, ge=-1, description="Most CoACD parts per concave piece, -1 for the part budget.")
    preprocess_mode: Annotated[Literal["auto", "on", "off"], Option("--coacd-preprocess")] = Field(
        default="auto",
        description="CoACD manifold preprocessing: auto, on or off (off is much faster on clean watertight meshes).")
    preprocess_resolution: int = Field(default=50, gt=0)
    resolution: int = Field(default=1000, gt=0, description="Sampling resolution of the concavity metric.")
    mcts_iterations: int = Field(default=60, gt=0, description="Monte Carlo tree search iterations per cut.")
    mcts_max_depth: int = Field(default=2, gt=0, description="Cuts the tree search looks ahead.")
    mcts_nodes: int = Field(default=10, gt=0, description="Candidate cutting planes per tree node.")
    seed: int = Field(default=0, ge=0)


class ColliderSettings(BaseModel):
    """How concave pieces become colliders (collider_export/methods.py); every field but the safety limit shapes
    the parts (cache key)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    mode: Annotated[Mode, Option("--colliders")] = Field(
        default="balanced", description="quality (CoACD, else voxel, else hull), balanced (hull, voxel or CoACD, "
                                        "whichever first fits the agent band) or fast (hull or voxel).")
    coacd: Annotated[CoacdParams, EXPAND] = CoacdParams()
    max_parts: Annotated[int, Option("--max-parts")] = Field(
        default=32, ge=1, description="Part budget per object; parts are merged to stay within it.")
    exact_max_parts: Annotated[int, Option("--exact-max-parts")] = Field(
        default=128, ge=1, description="Part budget of an object with a piece that only the last resort, exact "
                                       "voxels at the band tolerance, fits (never below --max-parts).")
    coacd_max_faces: Annotated[int, Option("--coacd-max-faces")] = Field(
        default=4000, ge=0, description="CoACD is tried only on pieces of at most this many faces.")
    piece_limit_s: Annotated[float, Option("--piece-limit")] = Field(
        default=600.0, gt=0, description="Safety stop, s: the export fails, naming the piece, when one method runs "
                                         "longer on it (it never picks a method).")
    band_tolerance_cm: Annotated[float, Option("--band-tolerance")] = Field(
        default=2.0, gt=0, description="A method is good enough when its agent-band footprint is within this many cm "
                                       "of the piece's.")
    voxel_pitch: float = Field(default=0.02, ge=0.01, le=0.1, description="Voxel size of the voxel method, m.")


class ExportConfig(BaseModel):
    """Settings of export-usd (workers never change outputs)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    colliders: Annotated[ColliderSettings, EXPAND] = ColliderSettings()
    convex_tolerance: float = Field(
        default=0.002, gt=0, lt=1, description="A closed piece within this relative volume of its hull is convex."
    )
    workers: Annotated[int, Option("--workers")] = Field(
        default=1, ge=1, description="Processes splitting meshes, decomposing pieces and measuring colliders.")
    usdz: Annotated[bool, Option("--usdz")] = Field(
        default=False, description="Also write scene.usdz (the stage and its layers in one package).")
    gaussians: Annotated[Literal["particlefield", "nurec"], Option("--gaussians")] = Field(
        default="particlefield", description="particlefield: ParticleField3DGaussianSplat prims per object (OpenUSD "
        "26.03+, Isaac Sim 6); nurec: gaussians.usdz, NuRec as NVIDIA 3DGRUT's ply_to_usd writes it (Isaac Sim 5).")
    layout: Annotated[Literal["sagebench", "sage"], Option("--layout")] = Field(
        default="sagebench", description="sagebench, or sage: also sage/<id>.usda in SAGE-3D's template form with its "
        "collision payload sage/<id>_collision.usd (needs --gaussians nurec).")

    @field_validator("layout")
    @classmethod
    def _sage_renders_nurec(cls, layout: str, info: ValidationInfo) -> str:
        if layout == "sage" and info.data.get("gaussians") != "nurec":
            raise ValueError("sage needs --gaussians nurec: SAGE-3D's template references a NuRec USDZ")
        return layout
