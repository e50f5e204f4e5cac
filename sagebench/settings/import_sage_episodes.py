"""import-sage-episodes' settings (defaults here, nowhere else): what a GVLN file does not say about its episodes."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from sagebench.settings.option import Option
from sagebench.settings.shared import Split


class SageImportConfig(BaseModel):
    """What a GVLN file does not say about its episodes."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    goal_radius: Annotated[float, Option("--goal-radius")] = Field(
        default=0.5, gt=0, description="Success radius, m, where the file has none (SAGE-3D's episodes_adapter.py's).")
    split: Annotated[Split, Option("--split")] = Field(default="test", description="Split of the rows where the file has none.")
