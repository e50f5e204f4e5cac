"""export-training's settings (defaults here, nowhere else): which episodes, the views and the shards."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, field_validator

from sagebench.settings.option import Option
from sagebench.settings.rollout import EnvConfig
from sagebench.settings.shared import RENDERER, SPLITS, ActionConfig, CameraConfig, RendererChoice


class TrainingExportConfig(BaseModel):
    """Settings of export-training."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    split: Annotated[str | None, Option("--split", values=SPLITS)] = Field(
        default=None, description="Export only this split (default: every split).")
    depth: Annotated[bool, Option("--depth")] = Field(
        default=False, description="Also write each view's expected depth (16-bit PNG, mm).")
    width: Annotated[int, Option("--width")] = Field(default=224, ge=8, le=4096, description="View width, px.")
    height: Annotated[int, Option("--height")] = Field(default=224, ge=8, le=4096, description="View height, px.")
    renderer: Annotated[RendererChoice, Option("--renderer")] = Field(default="auto", description=RENDERER)
    episodes_per_shard: Annotated[int, Option("--episodes-per-shard")] = Field(
        default=32, ge=1, description="Episodes per tar shard.")
    batch: Annotated[int, Option("--batch")] = Field(
        default=8, ge=1, description="Episodes stepped and rendered together.")
    workers: Annotated[int, Option("--workers")] = Field(default=2, ge=1, description="Threads stepping MuJoCo.")
    navila: Annotated[bool, Option("--navila")] = Field(
        default=False, description="Also write NaVILA's layout (OUT/navila/) from the shards.")
    camera: CameraConfig = CameraConfig()  # the body is the one the run's maps were built for
    actions: ActionConfig = ActionConfig()

    @field_validator("split")
    @classmethod
    def _known_split(cls, value: str | None) -> str | None:
        if value is not None and value not in SPLITS:
            raise ValueError(f"{value!r} is not one of {', '.join(SPLITS)}")
        return value

    def env(self) -> EnvConfig:
        return EnvConfig(width=self.width, height=self.height, camera=self.camera, actions=self.actions,
                         observations=("rgb", "depth") if self.depth else ("rgb",), privileged=("pose",),
                         max_steps=1_000_000, renderer=self.renderer)
