"""The per-scene stages of a run and the stamp that lets a re-run skip one; what each reads and writes, and
so which stages it waits for, comes from the run layout's CONTRACT.

A stage is skipped when its stamp (RUN/.stamps/<scene_id>/<stage>.json, sagebench.stamps) records the same
key — a hash of the versions, the stage's settings and every input file — and every output file it recorded
is still there with the same hash. Stamps are written after the outputs, so a run killed at any moment
re-runs exactly the stages whose stamps are missing or stale. The stage commands write the same stamps
(pipeline/stage_commands.py), so a run made stage by stage is skipped as well when its settings are the run's.
"""

from __future__ import annotations

import dataclasses
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sagebench import stamps, ui
from sagebench.errors import SagebenchError
from sagebench.run_layout import after, stage_files


@dataclass(frozen=True)
class Task:
    """One stage of one scene, everything a worker process needs (picklable)."""

    stage: str
    scene_id: str
    source: Path  # the artist scene directory
    run_dir: Path
    settings: dict[str, Any]  # the stage's config as JSON data
    cache_dir: Path | None = None


@dataclass(frozen=True)
class Outcome:
    stage: str
    scene_id: str
    status: str  # ran | skipped | failed
    seconds: float
    message: str = ""  # a summary line, or the error for a failure
    ok: bool = True  # False when the stage ran but judged its scene bad (validate failures)
    warnings: tuple[str, ...] = ()  # what the stage warned about; the driver prints them


def _run_build(t: Task) -> tuple[str, bool]:
    from sagebench.settings.build_scene import BuildSceneConfig
    from sagebench.stages.build_scene import build_scene

    return build_scene(t.source, t.run_dir, BuildSceneConfig.model_validate(t.settings)).summary(), True


def _run_gen(t: Task) -> tuple[str, bool]:
    from sagebench.stages.gen_trajectories import GenTrajectoriesConfig, gen_trajectories

    (result,) = gen_trajectories(t.run_dir, GenTrajectoriesConfig.model_validate(t.settings), scene_id=t.scene_id)
    return result.summary(), True


def _run_export(t: Task) -> tuple[str, bool]:
    from sagebench.settings.export_usd import ExportConfig
    from sagebench.stages.export_usd import export_usd

    (result,) = export_usd(t.run_dir, scene_id=t.scene_id, config=ExportConfig.model_validate(t.settings),
                           cache_dir=t.cache_dir)
    return result.line(), True


def _run_validate(t: Task) -> tuple[str, bool]:
    from sagebench.settings.validate import ValidateConfig
    from sagebench.stages.validate import validate_run

    (result,) = validate_run(t.run_dir, ValidateConfig.model_validate(t.settings), scene_id=t.scene_id,
                             against_records=False)  # run: the stamps vouch for its inputs; the manifest comes after
    return result.summary(), result.passed


@dataclass(frozen=True)
class Stage:
    name: str
    run: Callable[[Task], tuple[str, bool]]

    @property
    def after(self) -> tuple[str, ...]:
        return after(self.name)

    def inputs(self, t: Task) -> list[Path]:
        return stage_files(self.name, "reads", t.run_dir, t.scene_id, t.source)

    def cpus(self, t: Task) -> int:
        """CPUs the stage keeps busy: its `workers` setting (CoACD processes, replay threads), else one."""
        return int(t.settings.get("workers", 1))


STAGES: dict[str, Stage] = {s.name: s for s in (
    Stage("build_scene", _run_build),
    Stage("gen_trajectories", _run_gen),
    Stage("export_usd", _run_export),
    Stage("validate", _run_validate),
)}


def stage_key(task: Task, inputs: list[Path]) -> str:
    return stamps.stage_key(task.stage, task.settings, inputs, task.run_dir, task.source)


def stamp_path(task: Task) -> Path:
    return stamps.stamp_path(task.run_dir, task.scene_id, task.stage)


def up_to_date(task: Task, key: str) -> bool:
    stamp = stamps.read_stamp(task.run_dir, task.scene_id, task.stage)
    if stamp is None or stamp.get("key") != key:
        return False
    outputs = stamps.output_hashes(task.stage, task.run_dir, task.scene_id)
    return outputs == stamp["outputs"] and bool(outputs)


def run_task(task: Task) -> Outcome:
    """Run one stage of one scene unless its stamp says it is up to date; never raises. Its warnings come
    back in the outcome (a worker's stderr may go nowhere)."""
    with ui.collect_warnings() as found:
        outcome = _run_task(task)
    return dataclasses.replace(outcome, warnings=tuple(found))


def _run_task(task: Task) -> Outcome:
    start = time.perf_counter()
    stage = STAGES[task.stage]
    try:
        key = stage_key(task, stage.inputs(task))
        if up_to_date(task, key):
            stamp = stamps.read_stamp(task.run_dir, task.scene_id, task.stage) or {}
            return Outcome(task.stage, task.scene_id, "skipped", time.perf_counter() - start,
                           stamp.get("message", ""), stamp.get("ok", True))
        message, ok = stage.run(task)
        stamps.write_stamp(task.run_dir, task.scene_id, task.stage, key, message, ok)
        return Outcome(task.stage, task.scene_id, "ran", time.perf_counter() - start, message, ok)
    except SagebenchError as err:
        return Outcome(task.stage, task.scene_id, "failed", time.perf_counter() - start, str(err), False)
    except Exception as err:  # a crash in one scene (CoACD, a library) must not stop the others
        where = traceback.extract_tb(err.__traceback__)[-1]
        return Outcome(task.stage, task.scene_id, "failed", time.perf_counter() - start,
                       f"{type(err).__name__}: {err} ({Path(where.filename).name}:{where.lineno})", False)
