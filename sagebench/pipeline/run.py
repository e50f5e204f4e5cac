"""`sagebench run`: every stage over many scenes, skipping what is up to date, then the manifest and the
dataset card (README.md)."""

from __future__ import annotations

import contextlib
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

from sagebench import ui
from sagebench.episodes.card import card_text
from sagebench.errors import ConfigError
from sagebench.pipeline.config import resolve_scenes
from sagebench.pipeline.executors import make_executor
from sagebench.pipeline.kernels import compile_kernels
from sagebench.pipeline.pieces import PieceOutcome
from sagebench.pipeline.schedule import RunScheduler
from sagebench.pipeline.manifest import sha256_file, write_manifest
from sagebench.fileio import remove_temporaries, write_text
from sagebench.pipeline.tasks import STAGES, Outcome
from sagebench.run_layout import (
    BASELINES, CONTRACT, DATASET_CARD, OUTPUT_ROOTS, SCENE_FILE, SHARDS, STAMPS, after, root_dir, run_episodes_dir, stage_files,
)
from sagebench.run_folder import check_scenes_apart, claim_run_dir
from sagebench.scene.loader import parse_spec
from sagebench.settings.run import RunConfig


@dataclass
class RunSummary:
    run_dir: Path
    scenes: list[str]
    outcomes: list[Outcome] = field(default_factory=list)
    pieces: list[PieceOutcome] = field(default_factory=list)  # collider pieces run as tasks of their own
    nodes: dict[str, int] = field(default_factory=dict)  # Ray node id -> tasks it ran (empty: local)
    episodes: int = 0
    wall_seconds: float = 0.0

    @property
    def failed(self) -> dict[str, Outcome]:
        """scene id -> the first stage that failed it (an error, or validation failures)."""
        out: dict[str, Outcome] = {}
        for o in self.outcomes:
            if (o.status == "failed" or not o.ok) and o.scene_id not in out:
                out[o.scene_id] = o
        return out

    @property
    def ok(self) -> bool:
        return not self.failed

    def lines(self) -> list[str]:
        by_stage: dict[str, list[Outcome]] = defaultdict(list)
        for o in self.outcomes:
            by_stage[o.stage].append(o)
        lines = [f"run {self.run_dir}: {len(self.scenes)} scenes, {self.episodes} episodes, "
                 f"{len(self.scenes) - len(self.failed)} scenes complete in {self.wall_seconds:.1f} s"]
        for name in STAGES:
            got = by_stage.get(name, [])
            count = lambda s: sum(o.status == s for o in got)  # noqa: E731
            lines.append(f"  {name:<17} ran {count('ran'):>3}  skipped {count('skipped'):>3}  failed "
                         f"{count('failed') + sum(o.status == 'ran' and not o.ok for o in got):>3}  "
                         f"{sum(o.seconds for o in got):8.1f} s")
        if self.pieces:
            lines.append(f"  {'collider pieces':<17} ran {len(self.pieces):>3}  (a task each)"
                         f"{sum(p.seconds for p in self.pieces):19.1f} s")
        if self.nodes:
            tasks = ", ".join(f"{node[:8]} {n}" for node, n in sorted(self.nodes.items(), key=lambda kv: -kv[1]))
            lines.append(f"  {'ray nodes':<17} {len(self.nodes):>3}  tasks per node: {tasks}")
        for sid, o in sorted(self.failed.items()):
            lines.append(f"  FAILED {sid} at {o.stage}: {o.message}")
        return lines


def run_pipeline(config: RunConfig, config_path: Path, *, force: bool = False) -> RunSummary:
    """Run build-scene, gen-trajectories, export-usd and validate over every scene of the config.

    `out` must be absent, empty or a sagebench run (besides the config and the scenes it names), unless `force`
    (run_folder.claim_run_dir)."""
    start = time.perf_counter()
    sources = _scene_ids(resolve_scenes(config, config_path), config_path)
    run_dir = Path(config.out)
    check_scenes_apart(run_dir, sources.values(), path=config_path, out_field="out", scenes_field="scenes")
    with claim_run_dir(run_dir, "run", force=force, config=config_path, inputs=sources.values()):
        clean_temporaries(run_dir, sources.values())
        return _run_locked(config, config_path, sources, run_dir, start)


def _run_locked(config: RunConfig, config_path: Path, sources: dict[str, Path], run_dir: Path, start: float
                ) -> RunSummary:
    settings = {
        "build_scene": config.build_scene.model_dump(mode="json"),
        "gen_trajectories": config.gen_trajectories.model_dump(mode="json"),
        "export_usd": config.export_usd.model_dump(mode="json"),
        "validate": config.validate_.model_dump(mode="json"),
    }
    summary = RunSummary(run_dir=run_dir, scenes=sorted(sources))
    executor = make_executor(config.executor, config.workers, config.ray_address)
    try:
        if executor.capacity > 1:  # workers side by side would each compile the kernels a cold cache lacks
            compile_kernels()
        scheduler = RunScheduler(executor, sources, run_dir, settings, config.cache_dir)
        for outcome in ui.track(scheduler.outcomes(), "scenes x stages", total=len(sources) * len(STAGES)):
            summary.outcomes.append(outcome)
            ui.info(f"{outcome.status:>7} {outcome.stage} {outcome.scene_id}: {outcome.message}")
            for message in outcome.warnings:
                ui.warn(f"{outcome.scene_id} {outcome.stage}: {message}")
        summary.pieces, summary.nodes = scheduler.pieces, dict(executor.nodes)
    finally:
        executor.close()
    for sid, o in sorted(summary.failed.items()):
        if o.status == "failed":
            drop_stale_outputs(run_dir, sid, o.stage)
    summary.episodes = _count_episodes(run_dir, summary.scenes)
    summary.wall_seconds = time.perf_counter() - start
    write_manifest(run_dir, config=config.outputs_config(),
                   inputs={sid: _inputs_hash(run_dir, sid, src) for sid, src in sources.items()},
                   failed={sid: {"stage": o.stage, "message": o.message} for sid, o in summary.failed.items()})
    write_text(run_dir / DATASET_CARD, card_text(run_dir))
    return summary


def drop_stale_outputs(run_dir: Path, scene_id: str, failed: str) -> list[Path]:
    """Remove what the stage `failed` and every stage after it wrote for the scene in earlier runs, and their
    stamps: those files came from other inputs or settings, and the manifest must not list them as this run's
    (a failed LLM gen-trajectories would otherwise leave the last run's template shards listed). Hidden
    entries (the user's) stay. Returns the files removed."""
    stale = [name for name in STAGES if name == failed or failed in _comes_after(name)]
    doomed = [f for name in stale for f in stage_files(name, "writes", run_dir, scene_id)]
    doomed += [f for name in stale if (f := run_dir / STAMPS / scene_id / f"{name}.json").is_file()]
    for f in doomed:
        f.unlink(missing_ok=True)
    for name in stale:
        for place in CONTRACT[name].writes:
            top = root_dir(place.root, run_dir, scene_id) / place.rel
            if top.is_dir():
                for d in sorted((p for p in top.rglob("*") if p.is_dir()), key=lambda p: len(p.parts), reverse=True):
                    with contextlib.suppress(OSError):
                        d.rmdir()  # emptied directories only
                with contextlib.suppress(OSError):
                    top.rmdir()
    return doomed


def _comes_after(stage: str) -> set[str]:
    """Every stage `stage` waits for, directly or through another."""
    out: set[str] = set()
    todo = list(after(stage))
    while todo:
        name = todo.pop()
        if name not in out:
            out.add(name)
            todo.extend(after(name))
    return out


def _scene_ids(dirs: list[Path], config_path: Path) -> dict[str, Path]:
    """scene id -> scene directory; two directories with one scene id is an error."""
    out: dict[str, Path] = {}
    for d in dirs:
        spec_path = d / SCENE_FILE
        try:
            sid = parse_spec(spec_path.read_text(encoding="utf-8"), spec_path).scene_id
        except OSError:
            sid = d.name  # build-scene will report the unreadable scene as this scene's failure
        except Exception:  # a malformed scene.json fails that scene alone, at build-scene
            sid = d.name
        if sid in out:
            raise ConfigError(f"scene id {sid!r} is used by both {out[sid]} and {d}", path=config_path,
                              field="scenes")
        out[sid] = d
    return out


def clean_temporaries(run_dir: Path, scene_dirs) -> list[Path]:
    """Remove what a killed run left half-written: sagebench's own temporaries (fileio.is_temporary) in the
    trees a run writes and directly in RUN_DIR, never inside an input scene. Call it holding the run lock,
    so that no live process owns them."""
    trees = [run_dir / d for d in (*OUTPUT_ROOTS, STAMPS, BASELINES)]
    return remove_temporaries(trees, entries_of=[run_dir], keep_out=scene_dirs)


def _inputs_hash(run_dir: Path, scene_id: str, source: Path) -> str:
    """sha256 over the path and content hash of every source file build-scene reads."""
    import hashlib

    h = hashlib.sha256()
    for p in stage_files("build_scene", "reads", run_dir, scene_id, source):
        h.update(p.relative_to(source).as_posix().encode() + b"\0" + sha256_file(p).encode() + b"\0")
    return h.hexdigest()


def _count_episodes(run_dir: Path, scene_ids: list[str]) -> int:
    import pyarrow.parquet as pq

    return sum(pq.ParquetFile(p).metadata.num_rows
               for sid in scene_ids for p in sorted(run_episodes_dir(run_dir, sid).glob(SHARDS)))
