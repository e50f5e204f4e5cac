"""export-usd's settings (defaults here, nowhere else), apart from the code that uses them."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator

from sagebench.collider_export.methods import ColliderSettings


class ExportConfig(BaseModel):
    """Settings of export-usd; the CLI maps its options onto these fields (workers never change outputs)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    colliders: ColliderSettings = ColliderSettings()
    convex_tolerance: float = Field(
        default=0.002, gt=0, lt=1, description="A closed piece within this relative volume of its hull is convex."
    )
    workers: int = Field(default=1, ge=1,
                         description="Processes splitting meshes, decomposing pieces and measuring colliders.")
    usdz: bool = Field(default=False, description="Also package the stage and its layers as scene.usdz.")
    gaussians: Literal["particlefield", "nurec"] = Field(
        default="particlefield", description="particlefield: per-object ParticleField3DGaussianSplat prims (OpenUSD "
        "26.03+, Isaac Sim 6); nurec: one NuRec USDZ as NVIDIA 3DGRUT's ply_to_usd writes it (Isaac Sim 5).")
    layout: Literal["sagebench", "sage"] = Field(
        default="sagebench", description="sage: also sage/<scene_id>.usda in SAGE-3D's template form, with its "
        "collision payload (needs --gaussians nurec).")

    @field_validator("layout")
    @classmethod
    def _sage_renders_nurec(cls, layout: str, info: ValidationInfo) -> str:
        if layout == "sage" and info.data.get("gaussians") != "nurec":
            raise ValueError("sage needs --gaussians nurec: SAGE-3D's template references a NuRec USDZ")
        return layout
