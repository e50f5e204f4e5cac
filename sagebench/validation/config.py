"""validate's settings (defaults here, nowhere else), apart from the code that uses them."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from sagebench.config import CameraConfig
from sagebench.render.backends import RendererChoice
from sagebench.replay.physics import ReplayConfig
from sagebench.validation.checks import CheckConfig


class ValidateConfig(BaseModel):
    """Settings of validate (defaults here, nowhere else); the CLI maps its options onto these fields."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    camera: CameraConfig = CameraConfig()
    replay: ReplayConfig = ReplayConfig()
    checks: CheckConfig = CheckConfig()
    frames_per_scene: int = Field(default=3, ge=0, description="Trajectories per scene with spot-check frames.")
    depth_tolerance: float = Field(default=0.10, gt=0, description="Largest median |splat - collider depth| per frame, m.")
    frame_width: int = Field(default=320, ge=8, le=4096, description="Spot-check frame width, px.")
    frame_height: int = Field(default=240, ge=8, le=4096, description="Spot-check frame height, px.")
    ray_stride: int = Field(default=8, ge=1, description="Collider rays are cast every this many pixels.")
    min_alpha: float = Field(default=0.5, gt=0, le=1, description="Splat pixels this opaque are compared.")
    min_compared_fraction: float = Field(default=0.25, gt=0, le=1, description=(
        "A frame whose compared pixels (opaque splat and a collider hit) are fewer than this fraction of the "
        "sampled ones fails alignment."))
    workers: int = Field(default=2, ge=1, description="Threads stepping the MuJoCo replays.")
    seed: int = Field(default=0, description="Picks the spot-checked trajectories.")
    renderer: RendererChoice = Field(default="cpu", description=(
        "Renderer of the spot-check frames: cpu (the reference), gsplat (CUDA GPU; the instance-id frames still "
        "come from the CPU renderer) or auto."))
