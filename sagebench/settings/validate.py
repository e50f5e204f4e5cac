"""validate's settings (defaults here, nowhere else): the replay, the verdict's tolerances and the spot-check
frames; run.toml's [validate] table."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from sagebench.settings.option import Option
from sagebench.settings.shared import RENDERER, CameraConfig, RendererChoice, ReplayConfig


class CheckConfig(BaseModel):
    """Tolerances of the verdict (validation/checks.py)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    penetration_tolerance: float = Field(
        default=0.01, ge=0, description="Deepest contact allowed, m (MuJoCo soft-contact slack; reference paths keep clear).")
    deviation_tolerance: float = Field(
        default=0.10, ge=0, description="How far contact may push the agent off the commanded polyline, m.")
    min_csr: float = Field(default=1.0, ge=0, le=1, description="Lowest CSR that passes.")


class ValidateConfig(BaseModel):
    """Settings of validate."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    camera: CameraConfig = CameraConfig()
    replay: ReplayConfig = ReplayConfig()
    checks: CheckConfig = CheckConfig()
    frames_per_scene: Annotated[int, Option("--frames-per-scene")] = Field(
        default=3, ge=0, description="Trajectories per scene rendered at start, middle and goal (the spot-check "
                                     "frames).")
    depth_tolerance: Annotated[float, Option("--depth-tolerance")] = Field(
        default=0.10, gt=0, description="Largest median |splat - collider depth| per frame, m.")
    frame_width: int = Field(default=320, ge=8, le=4096, description="Spot-check frame width, px.")
    frame_height: int = Field(default=240, ge=8, le=4096, description="Spot-check frame height, px.")
    ray_stride: int = Field(default=8, ge=1, description="Collider rays are cast every this many pixels.")
    min_alpha: float = Field(default=0.5, gt=0, le=1, description="Splat pixels this opaque are compared.")
    min_compared_fraction: float = Field(default=0.25, gt=0, le=1, description=(
        "A frame whose compared pixels (opaque splat and a collider hit) are fewer than this fraction of the "
        "sampled ones fails alignment."))
    workers: Annotated[int, Option("--workers")] = Field(
        default=2, ge=1, description="Threads stepping the MuJoCo replays.")
    seed: int = Field(default=0, description="Picks the spot-checked trajectories.")
    renderer: Annotated[RendererChoice, Option("--renderer")] = Field(
        default="cpu", description=f"{RENDERER} Instance-id frames come from the CPU.")
