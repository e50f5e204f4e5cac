"""report's settings (defaults here, nowhere else)."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

from sagebench.settings.option import Option
from sagebench.settings.shared import RENDERER, RendererChoice


class ReportConfig(BaseModel):
    """Settings of report."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    views: Annotated[bool, Option("--no-views")] = Field(default=True, description=(
        "The start and goal views of each trajectory, rendered from the Gaussians; --no-views leaves them out "
        "(nothing is rendered)."))
    renderer: Annotated[RendererChoice, Option("--renderer")] = Field(default="cpu", description=RENDERER)
