"""What a report shows of a run, read from its finished outputs: each scene's episode rows, maps and validate's
results, and the facts its dataset card states."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq

from sagebench.episodes.card import card_licence, scene_licences, size_category
from sagebench.episodes.episode import NO_LEVEL
from sagebench.episodes.shards import read_episodes
from sagebench.errors import DataError
from sagebench.run_layout import (
    CONTRACT, DATASET_CARD, MANIFEST, REPORT, TOPDOWN, TOPDOWN_PNG, VALIDATION_SHARD, require, run_episodes_dir,
    run_reports_dir, run_scene_dir, run_scenes, run_validation_dir,
)
from sagebench.settings.shared import SPLITS
from sagebench.topdown.grid_file import TopdownGrids, read_topdown_grids


@dataclass(frozen=True)
class SceneFacts:
    scene_id: str
    rows: list[dict]  # episode rows, every column, in file order
    grids: TopdownGrids
    map_png: Path  # RUN/scenes/<id>/topdown.png
    validation: dict[str, dict]  # trajectory_id -> validate's row; empty when the scene was not validated
    report: dict | None  # validate's report.json

    def trajectories(self) -> dict[str, list[dict]]:
        """The rows of each trajectory, in file order."""
        out: dict[str, list[dict]] = {}
        for row in self.rows:
            out.setdefault(row["trajectory_id"], []).append(row)
        return out


@dataclass(frozen=True)
class RunFacts:
    run_dir: Path
    scenes: list[SceneFacts]
    card: dict[str, str]  # the dataset card's key facts, by name
    version: str | None  # sagebench's version in manifest.json, None without one


def read_run(run_dir: Path, scene_id: str | None = None) -> RunFacts:
    """The facts of every scene with episodes (or of `scene_id`); a missing map is a DataError naming the command
    that writes it."""
    run_dir = Path(run_dir)
    scenes = []
    for sid in run_scenes(run_dir, scene_id, having="episodes"):
        require(CONTRACT["report"].reads, run_dir, sid)
        scene_dir = run_scene_dir(run_dir, sid)
        scenes.append(SceneFacts(sid, _rows(run_dir, sid), read_topdown_grids(scene_dir / TOPDOWN),
                                 scene_dir / TOPDOWN_PNG, _validation(run_dir, sid), _report(run_dir, sid)))
    version = _json(run_dir / MANIFEST, {}).get("sagebench_version")
    return RunFacts(run_dir, scenes, card_facts(run_dir, scenes), version)


def card_facts(run_dir: Path, scenes: list[SceneFacts]) -> dict[str, str]:
    """What the dataset card (episodes/card.py) says of these scenes: licence, size, splits, configs."""
    rows = sum(len(s.rows) for s in scenes)
    splits = [s for s in SPLITS if any(r.get("split") == s for sc in scenes for r in sc.rows)]
    licences = {k: v for k, v in scene_licences(run_dir).items() if k in {s.scene_id for s in scenes}}
    card = run_dir / DATASET_CARD
    return {"dataset card": f"{DATASET_CARD} (written by sagebench run)" if card.is_file() else "none (sagebench run "
            "writes it)", "licence": card_licence(licences), "size category": size_category(rows),
            "episode rows": f"{rows:,}", "splits": ", ".join(splits) or "none",
            "configs": "episodes" + (", validation" if any(s.validation for s in scenes) else "")}


def _rows(run_dir: Path, sid: str) -> list[dict]:
    """The scene's episode rows; a row without a split, level or type (bare trajectories, shards older than the
    split column) has NO_LEVEL there, as scoring groups it."""
    try:
        rows = read_episodes(run_episodes_dir(run_dir, sid)).to_pylist()
    except (OSError, pa.ArrowException) as err:
        raise DataError(f"cannot read episode shards: {err}", path=run_episodes_dir(run_dir, sid)) from None
    return [r | {k: r.get(k) or NO_LEVEL for k in ("split", "instruction_level", "instruction_type")} for r in rows]


def _validation(run_dir: Path, sid: str) -> dict[str, dict]:
    path = run_validation_dir(run_dir, sid) / VALIDATION_SHARD
    if not path.is_file():
        return {}
    try:
        rows = pq.ParquetFile(path).read().to_pylist()  # not read_table: pyarrow.dataset imports pandas
    except (OSError, pa.ArrowException) as err:
        raise DataError(f"cannot read validate's results: {err}", path=path) from None
    return {r["trajectory_id"]: r for r in rows if isinstance(r.get("trajectory_id"), str)}


def _report(run_dir: Path, sid: str) -> dict | None:
    return _json(run_reports_dir(run_dir, sid) / REPORT, None)


def _json(path: Path, missing):  # noqa: ANN001, ANN202 - a default of any type
    """A JSON object file, `missing` when there is none; a malformed one is a DataError."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return missing
    except (OSError, ValueError) as err:
        raise DataError(f"cannot read: {err}", path=path) from None
    if not isinstance(doc, dict):
        raise DataError("not a JSON object", path=path)
    return doc
