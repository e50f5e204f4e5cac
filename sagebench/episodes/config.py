"""gen-trajectories' settings (defaults here, nowhere else): sampling, instructions, splits and what is written."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from sagebench.astar.sampling import SamplingConfig
from sagebench.episodes.splits import SplitConfig
from sagebench.instructions.base import HIGH_LEVEL_TYPES
from sagebench.instructions.llm_client import LLMConfig


class GenTrajectoriesConfig(SamplingConfig):
    """Settings of gen-trajectories: sampling plus what is written (defaults here, nowhere else)."""

    shard_mb: float = Field(default=128.0, gt=0, description="Largest Parquet shard, MB (one split per shard).")
    instructions: Literal["template", "llm", "none"] = Field(
        default="template",
        description="template: Base_Action, Single_Goal and one high-level row per trajectory; llm: the high-level "
                    "row from a chat model (grounded, else the template); none: one bare row per trajectory.")
    high_level_mix: dict[Literal[HIGH_LEVEL_TYPES], float] = Field(  # type: ignore[valid-type]
        default={t: 1.0 for t in HIGH_LEVEL_TYPES},
        description="Relative share of each high-level type (a type that cannot describe a goal is skipped).")
    llm: LLMConfig = Field(default=LLMConfig(), description="Chat model for --instructions llm.")
    goal_radius_m: float = Field(
        default=1.0, gt=0,
        description="Success radius, m: the stand point is ~0.2-0.3 m from the target, so 1 m means next to it.")
    preview_paths: int = Field(default=40, ge=0, description="Paths drawn in paths.png.")
    splits: SplitConfig = Field(default=SplitConfig(), description="Split fractions and seed (episodes/splits.py).")

    @model_validator(mode="after")
    def _instruction_settings(self) -> GenTrajectoriesConfig:
        if any(v < 0 for v in self.high_level_mix.values()) or not any(v > 0 for v in self.high_level_mix.values()):
            raise ValueError("high_level_mix needs non-negative shares, at least one positive")
        if self.instructions == "llm" and not (self.llm.base_url and self.llm.model):
            raise ValueError("--instructions llm needs --llm-base-url and --llm-model")
        if self.instructions != "llm" and self.llm != LLMConfig():
            raise ValueError("--llm-* options (the llm table) are used only with --instructions llm")
        return self
