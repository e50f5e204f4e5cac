"""export-usd's settings (defaults here, nowhere else), apart from the code that uses them."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

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
