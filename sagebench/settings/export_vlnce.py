"""export-vlnce's settings: how the dataset's instruction_tokens are made, declared with rollout's
(settings/shared.py), so a dataset and a closed loop given the same options give the same ids."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict

from sagebench.settings.shared import TokenizerSetting, VocabSetting


class VlnceExportConfig(BaseModel):
    """Settings of export-vlnce."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    tokenizer: TokenizerSetting
    vocab: VocabSetting
