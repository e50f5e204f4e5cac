"""The rollout record: what a rollout was asked to run and what its agent observed, beside its predictions.

`sagebench rollout --out P.jsonl` writes P_rollout.json (`record_path`): the episode ids it was asked to run (in
run order), the observations the policy got (profile, keys, the privileged ones), the success distance it used,
the settings that decide its output (for --resume), the episodes the policy failed, and whether every asked
episode has its line in P. `evaluate` reads it to score exactly the asked episodes (a missing one scores the
worst value of every metric) and prints the observations beside the scores.
"""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from sagebench.errors import DataError, first_error
from sagebench.fileio import write_text
from sagebench.input_files import read_regular

RECORD_FORMAT = 1
RECORD_BYTES = 1 << 28  # far beyond a record of a million episode ids; a bigger file is not one


class PolicyFailed(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    episode_id: str
    reason: str = Field(description="Why the policy's request failed (one line).")


class Observed(BaseModel):
    """What a policy observed during a rollout."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    profile: str = Field(description="The observation profile (custom, vlnce, sage, full).")
    keys: dict[str, str] = Field(description="Each observation the policy got and what it holds.")
    privileged: list[str] = Field(description="The privileged ones among them (pose, gps_compass, instance), and "
                                              "'episode' when the policy read the episode itself (a baseline).")

    def line(self) -> str:
        keys = "; ".join(f"{k} {v}" for k, v in self.keys.items())
        return f"{self.profile} profile: {keys}; privileged: {', '.join(self.privileged) or 'none'}"


class RolloutRecord(BaseModel):
    """P_rollout.json beside a rollout's predictions P.jsonl."""

    model_config = ConfigDict(extra="forbid", frozen=True,
                              title="sagebench rollout record (beside a rollout's predictions)")

    format: int = Field(default=RECORD_FORMAT, description="Version of this file's layout.")
    policy: str = Field(description="The policy: a built-in's name or the server's URL.")
    episodes: list[str] = Field(description="Episode ids the rollout was asked to run, in run order.")
    observations: Observed = Field(description="What the policy observed.")
    success_distance: float | None = Field(default=None, description="Success radius used instead of each "
                                                                      "episode's goal_radius (a preset), m.")
    settings: dict = Field(description="The settings that decide the predictions (rollout --resume keeps them).")
    failed_by_policy: list[PolicyFailed] = Field(default_factory=list,
                                                 description="Episodes whose policy requests failed; not in the "
                                                             "predictions (rollout --resume runs them again).")
    complete: bool = Field(default=False, description="Every asked episode has its line in the predictions.")


def record_path(predictions: Path) -> Path:
    """P_rollout.json for predictions P.jsonl."""
    p = Path(predictions)
    return p.with_name(p.stem + "_rollout.json")


def read_record(predictions: Path) -> RolloutRecord | None:
    """The record beside `predictions`, None when there is none; a malformed one is a DataError."""
    path = record_path(predictions)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return None
    except (OSError, UnicodeDecodeError) as err:
        raise DataError(f"cannot read: {err}", path=path) from None
    try:
        return RolloutRecord.model_validate_json(text)
    except ValidationError as err:
        field, msg, _ = first_error(err)
        raise DataError(msg, path=path, field=field) from None


def is_record(path: Path) -> bool:
    """Whether `path` is a rollout record sagebench wrote: a regular file that parses as one."""
    data = read_regular(path, limit=RECORD_BYTES)
    try:
        return data is not None and RolloutRecord.model_validate_json(data) is not None
    except ValidationError:
        return False


def is_rollout_predictions(path: Path) -> bool:
    """Whether `path` holds a rollout's predictions: the rollout record beside it is sagebench's."""
    return is_record(record_path(path))


def write_record(predictions: Path, record: RolloutRecord) -> None:
    """Write the record beside `predictions` whole (atomic)."""
    write_text(record_path(predictions), record.model_dump_json(indent=1) + "\n")
