"""The TOML run config of `sagebench run` (defaults here, nowhere else): which scenes, where to, how to run them,
and each scene stage's settings table."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from sagebench.settings.build_scene import BuildSceneConfig
from sagebench.settings.export_usd import ExportConfig
from sagebench.settings.gen_trajectories import GenTrajectoriesConfig
from sagebench.settings.option import Option
from sagebench.settings.validate import ValidateConfig

# Settings that change how fast a run goes but never what it writes; they stay out of the manifest.
EXECUTION_KEYS = frozenset({"out", "workers", "executor", "ray_address", "cache_dir"})


class RunConfig(BaseModel):
    """A multi-scene run. Relative paths are relative to the config file's directory. The run command's options
    replace the config's execution settings."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    scenes: list[str] = Field(min_length=1, description="Scene directories or glob patterns.")
    out: Path = Field(description="Run directory.")
    seed: int | None = Field(default=None, description="When set, the seed of every stage that has none of its own.")
    workers: Annotated[int, Option("--workers")] = Field(
        default=1, ge=1, description="Tasks run at once by the local executor: scene stages and collider pieces.")
    executor: Annotated[Literal["local", "ray"], Option("--executor")] = Field(
        default="local", description="local or ray.")
    ray_address: Annotated[str | None, Option("--ray-address")] = Field(
        default=None, description="Ray cluster address; none starts a local Ray.")
    cache_dir: Path | None = Field(default=None, description="CoACD cache (default: the user cache directory).")
    build_scene: BuildSceneConfig = BuildSceneConfig()
    gen_trajectories: GenTrajectoriesConfig = GenTrajectoriesConfig()
    export_usd: ExportConfig = ExportConfig()
    validate_: ValidateConfig = Field(default=ValidateConfig(), alias="validate")

    def outputs_config(self) -> dict[str, Any]:
        """What determines the outputs (the manifest's `config`): everything but execution settings."""
        return self.model_dump(mode="json", by_alias=True, exclude=set(EXECUTION_KEYS))
