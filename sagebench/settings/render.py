"""render's settings (defaults here, nowhere else): the view of one rendered image."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from sagebench.settings.option import EXPAND, Option
from sagebench.settings.shared import RENDERER, CameraConfig, RendererChoice


class RenderConfig(BaseModel):
    """The view: the agent's camera (CameraConfig), tilted by pitch_deg."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    camera: Annotated[CameraConfig, EXPAND] = CameraConfig()
    pitch_deg: Annotated[float, Option("--pitch")] = Field(
        default=0.0, gt=-90, lt=90, description="Camera tilt up, degrees (negative looks down).")
    width: Annotated[int, Option("--width")] = Field(default=640, ge=1, le=8192, description="Image width, px.")
    height: Annotated[int, Option("--height")] = Field(default=480, ge=1, le=8192, description="Image height, px.")
    renderer: Annotated[RendererChoice, Option("--renderer")] = Field(default="cpu", description=RENDERER)
