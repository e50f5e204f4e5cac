"""Agent predictions as JSON Lines: the row model, the reader (file:line errors) and the canonical writer.

One object per line (blank lines are skipped):
`{"episode_id": str, "poses": [[x, y, z, yaw], ...], "stopped": bool, "collision_intensity": [c, ...]}`.
`poses` are world metres and radians (Z up, yaw counter-clockwise from +X), row 0 the start, one row per agent
step; `stopped` says the agent ended the episode itself (SR needs it); the optional `collision_intensity` gives
c(t) in [0, 1] per pose (the fraction of that step's commanded motion contact blocked; 0 for row 0). Without
it, evaluate derives c(t) by replaying each step against the scene's colliders. `intensity_source` "simulator"
marks c(t) that `sagebench rollout` measured (absent: the agent's own report).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from sagebench.errors import DataError, field_path, first_error
from sagebench.fileio import write_text
from sagebench.input_files import read_input

Pose = tuple[float, float, float, float]
MAX_POSES = 10_000  # per episode: 20 times the simulator's 500-step default; metrics allocate poses x path points
MAX_LINE_CHARS = 4_000_000  # a line of MAX_POSES poses at full float precision is about 1.5 MB
POSE_MARGIN_M = 50.0  # how far outside its scene's map a pose may lie: far past where the simulator ends an episode
# (one step over the edge) or a step through a wall lands, near enough that no metric overflows
MAX_YAW = 1e5  # rad either way: an unwrapped heading of 10,000 half turns still fits


class Prediction(BaseModel):
    """One line of predictions.jsonl: what an agent did in one episode."""

    model_config = ConfigDict(
        extra="forbid", frozen=True, strict=True, allow_inf_nan=False,
        title="sagebench prediction (one line of predictions.jsonl, JSON Lines)",
    )

    episode_id: str = Field(min_length=1, description="episode_id of a row of RUN/episodes/<scene_id>/.")
    poses: list[Pose] = Field(
        min_length=1, max_length=MAX_POSES,
        description="Agent poses [x, y, z, yaw] per step (world metres, radians CCW from +X), row 0 the start.")
    stopped: bool = Field(description="True when the agent ended the episode itself (STOP); SR requires it.")
    collision_intensity: list[Annotated[float, Field(ge=0, le=1)]] | None = Field(
        default=None,
        description="Optional c(t) in [0, 1] per pose: fraction of the step's commanded motion that contact "
                    "blocked (0 for row 0). When absent, evaluate replays the poses against the colliders.")
    intensity_source: Literal["simulator"] | None = Field(
        default=None,
        description="'simulator' when sagebench rollout measured collision_intensity in its MuJoCo simulator; "
                    "absent when the agent reported it itself. evaluate reports each episode's ICP source.")

    @model_validator(mode="after")
    def _one_intensity_per_pose(self) -> Prediction:
        if self.intensity_source is not None and self.collision_intensity is None:
            raise ValueError("intensity_source without collision_intensity")
        if self.collision_intensity is not None and len(self.collision_intensity) != len(self.poses):
            raise ValueError(f"collision_intensity has {len(self.collision_intensity)} values for "
                             f"{len(self.poses)} poses (one per pose)")
        return self


def parse_line(text: str, path: Path, line: int) -> Prediction:
    """One JSON Lines row; a bad row is a DataError naming `path:line` and the field. A line too long to hold at most
    MAX_POSES poses is refused before it is parsed."""
    if len(text) > MAX_LINE_CHARS:
        raise DataError(f"the line is {len(text):,} characters, over {MAX_LINE_CHARS:,}: an episode has at most "
                        f"{MAX_POSES:,} poses", path=f"{path}:{line}")
    try:
        return Prediction.model_validate_json(text)
    except ValidationError as err:
        field, msg, e = first_error(err)
        if e["type"] == "missing" and len(e["loc"]) == 3 and e["loc"][0] == "poses":
            msg, field = "a pose is [x, y, z, yaw]: 4 numbers", field_path(e["loc"][:2])
        raise DataError(msg, path=f"{path}:{line}", field=field) from None


def read_predictions(path: Path, *, allow_empty: bool = False) -> list[tuple[int, Prediction]]:
    """(line number, prediction) for every non-blank line of a JSON Lines file, in file order; an empty file is
    a DataError unless `allow_empty` (a rollout whose policy failed every episode)."""
    path = Path(path)
    if not path.exists():
        raise DataError("no such file", path=path)
    try:
        text = read_input(path).decode("utf-8")
    except UnicodeDecodeError as err:
        raise DataError(f"cannot read: not UTF-8 text ({err.reason})", path=path) from None
    rows = [(n, parse_line(t, path, n)) for n, t in enumerate(text.splitlines(), start=1) if t.strip()]
    if not rows and not allow_empty:
        raise DataError("no predictions (the file is empty)", path=path)
    return rows


def check_on_map(rows: Sequence[tuple[int, Prediction]], bounds_of: Callable[[str], tuple[float, float, float, float]],
                 path: Path) -> None:
    """A DataError at the first pose whose (x, y) lies more than POSE_MARGIN_M outside the map (x0, y0, x1, y1) of
    its episode's scene, or whose yaw is past MAX_YAW: no agent there stands so, and scoring would overflow."""
    m = POSE_MARGIN_M
    for n, p in rows:
        x0, y0, x1, y1 = bounds_of(p.episode_id)
        x, y, yaw = np.asarray(p.poses, dtype=np.float64)[:, [0, 1, 3]].T
        off = (x < x0 - m) | (x > x1 + m) | (y < y0 - m) | (y > y1 + m)
        if (off | (np.abs(yaw) > MAX_YAW)).any():
            k = int(np.argmax(off | (np.abs(yaw) > MAX_YAW)))
            what = (f"({x[k]:g}, {y[k]:g}) lies more than {m:g} m outside the scene's map (x {x0:g}..{x1:g}, "
                    f"y {y0:g}..{y1:g} m)" if off[k] else f"yaw {yaw[k]:g} rad is past {MAX_YAW:g} either way")
            raise DataError(what, path=f"{path}:{n}", field=f"poses[{k}]")


def match_episodes(rows: Sequence[tuple[int, Prediction]], episode_ids: Iterable[str], path: Path, *,
                   allow_missing: bool = False) -> tuple[dict[str, Prediction], list[str]]:
    """Pair predictions with the episodes being scored: ({episode_id: prediction}, missing ids sorted).

    A duplicate or unknown episode id is a DataError at its line; episodes without a prediction are a DataError
    unless `allow_missing` (then they are returned to be scored as failures).
    """
    wanted = set(episode_ids)
    first_line: dict[str, int] = {}
    unknown = [(n, p.episode_id) for n, p in rows if p.episode_id not in wanted]
    if unknown:
        n, eid = unknown[0]
        raise DataError(f"unknown episode id {eid!r}: not an episode being evaluated ({len(unknown)} unknown in all)",
                        path=f"{path}:{n}", field="episode_id")
    for n, p in rows:
        if p.episode_id in first_line:
            raise DataError(f"duplicate episode id {p.episode_id!r} (first on line {first_line[p.episode_id]})",
                            path=f"{path}:{n}", field="episode_id")
        first_line[p.episode_id] = n
    missing = sorted(wanted - first_line.keys())
    if missing and not allow_missing:
        shown = ", ".join(missing[:3]) + (", ..." if len(missing) > 3 else "")
        raise DataError(f"{len(missing)} of {len(wanted)} episodes have no prediction ({shown}); "
                        "pass --allow-missing to score them as failures", path=path)
    return {p.episode_id: p for _, p in rows}, missing


def dumps_prediction(prediction: Prediction) -> str:
    """One canonical JSON line (keys in schema order, no spaces, optional fields left out when None)."""
    return prediction.model_dump_json(exclude_none=True)


def write_predictions(path: Path, predictions: Iterable[Prediction]) -> None:
    """Write predictions.jsonl whole (atomic), one line per prediction in the order given."""
    write_text(Path(path), "".join(dumps_prediction(p) + "\n" for p in predictions))
