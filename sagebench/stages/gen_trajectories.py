"""`gen-trajectories`: A* episodes with instructions (and the other tasks' episodes), from build-scene's maps to
Parquet shards.

Reads RUN/scenes/<scene_id>/{topdown.npz, semantic_map.json, scene.json}; writes
RUN/episodes/<scene_id>/part-<split>-NNNNN.parquet and RUN/previews/<scene_id>/paths.png, replacing each
directory whole; the preview lives outside episodes/ so that directory reads as one Parquet dataset.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from shapely.geometry import MultiPolygon, Polygon

from sagebench import ui
from sagebench.astar.sampling import GridMap, SamplingResult, sample_trajectories
from sagebench.episodes.preview import render_paths
from sagebench.episodes.rows import EpisodeRows, episode_rows
from sagebench.episodes.task_rows import scene_map, task_rows
from sagebench.episodes.tasks import NOGOAL_INSTRUCTION, TASK_SCHEMA, VLN, schema_for
from sagebench.episodes.shards import write_shards
from sagebench.episodes.targets import scene_context, scene_sight, scene_targets, unreachable_rooms
from sagebench.errors import ConfigError, DataError, ServiceError
from sagebench.fileio import staged_dir, write_bytes
from sagebench.instructions.execution import BlockedMap
from sagebench.instructions.llm_client import API_KEY_ENV, check_cache_dir, default_cache_dir
from sagebench.run_layout import (
    CONTRACT, PREVIEW, SCENE_FILE, SEMANTIC_MAP, TOPDOWN, require, run_episodes_dir, run_previews_dir, run_scene_dir,
    run_scenes,
)
from sagebench.scene.loader import parse_spec
from sagebench.scene.model import SceneSpec
from sagebench.settings.gen_trajectories import GenTrajectoriesConfig
from sagebench.settings.option import from_options, settings_of
from sagebench.topdown.grid_file import read_topdown_grids
from sagebench.topdown.semantic_map import SemanticMap, read_semantic_map

if TYPE_CHECKING:
    from sagebench.instructions.llm import LLMInstructor


def make_config(given: Mapping[str, object]) -> GenTrajectoriesConfig:
    """The settings from the options given ({"--per-scene": 8}); a bad value is a ConfigError naming the option.

    An --llm-* option without --instructions llm is an error even when it repeats the default.
    """
    llm = [s.name for s in settings_of(GenTrajectoriesConfig) if s.path.startswith("llm.") and s.name in given]
    if llm and given.get("--instructions") != "llm":
        raise ConfigError("used only with --instructions llm", field=llm[0])
    return from_options(GenTrajectoriesConfig, given)


@dataclass(frozen=True)
class SceneEpisodes:
    """What gen-trajectories wrote for one scene."""

    scene_id: str
    out_dir: Path
    trajectories: int
    rows: int
    shards: list[Path]
    llm_summary: str | None = None  # what the chat model contributed, in llm mode
    unreachable_rooms: tuple[str, ...] = ()  # rooms whose objects (and themselves) were no start or goal
    high_level_summary: str | None = None  # the high-level types' counts against their quotas, and why any fell short
    by_task: dict[str, tuple[int, int]] = field(default_factory=dict)  # task -> (trajectories, rows); {} for vln alone

    def summary(self) -> str:
        line = (f"gen-trajectories {self.scene_id}: {self.trajectories} trajectories, {self.rows} episode rows "
                f"in {len(self.shards)} shard(s) -> {self.out_dir}")
        if self.unreachable_rooms:
            line += (f"\n  left out (unreachable: most of the navigable floor outside the main region): rooms "
                     f"{', '.join(self.unreachable_rooms)} and the objects in them")
        if self.high_level_summary is not None:
            line += f"\n  high-level types: {self.high_level_summary}"
        if self.by_task:
            line += "\n  by task: " + "; ".join(f"{task} {t} trajectories, {n} episode rows"
                                                for task, (t, n) in self.by_task.items())
        return line if self.llm_summary is None else f"{line}\n  llm: {self.llm_summary}"


def gen_trajectories(run_dir: Path, config: GenTrajectoriesConfig, *, scene_id: str | None = None,
                     api_key: str | None = None) -> list[SceneEpisodes]:
    """Sample, instruct and write the episodes of every scene in RUN_DIR/scenes (or only `scene_id`).

    api_key: the LLM bearer token (default: the environment variable SAGEBENCH_LLM_API_KEY, never another).
    """
    scene_dirs = [run_scene_dir(run_dir, sid) for sid in run_scenes(run_dir, scene_id)]
    if config.instructions == "llm":
        cache_dir = config.llm.cache_dir or default_cache_dir()
        problem = check_cache_dir(Path(cache_dir))
        if problem is not None:
            raise ConfigError(problem, path=cache_dir, field="--llm-cache-dir")
    key = os.environ.get(API_KEY_ENV) if api_key is None else api_key
    return [generate_scene(d, run_dir, config, api_key=key)
            for d in ui.track(scene_dirs, "gen-trajectories")]


def generate_scene(scene_dir: Path, run_dir: Path, config: GenTrajectoriesConfig, *,
                   api_key: str | None = None) -> SceneEpisodes:
    """One scene: read its maps, sample the episodes of every task asked for, write its shards into
    RUN/episodes/<id>/ and the paths preview into RUN/previews/<id>/ (each replaced whole).

    In llm mode, a scene whose high-level rows come from the model less often than `llm.min_share`
    (or never) is a ServiceError and nothing is written.
    """
    spec, smap, grid, occupancy = read_scene_inputs(scene_dir)
    vln = _vln_rows(scene_dir, spec, smap, grid, occupancy, config, api_key) if VLN in config.tasks else None
    rooms = {r.id: MultiPolygon([Polygon(r.polygon)]) for r in spec.rooms}
    tasks = task_rows(spec.scene_id, smap, scene_map(grid, rooms), config, scene_dir / SEMANTIC_MAP)
    tasks, llm = _llm_nogoal(tasks, config, vln, api_key)
    schema = schema_for(config.tasks)
    rows = [({**r, "task": VLN} if schema is TASK_SCHEMA else r) for r in (vln.made.rows if vln else [])]
    rows += [r for task in sorted(tasks) for r in tasks[task]]
    paths = [t.waypoints for t in vln.result.trajectories] if vln else []
    paths += [np.asarray(r["reference_path"]) for task in sorted(tasks) for r in tasks[task]]
    png = render_paths(grid.navigable, occupancy, paths[:config.preview_paths], grid.resolution, grid.origin)
    out_dir = run_episodes_dir(run_dir, spec.scene_id)
    with staged_dir(out_dir) as tmp:
        shards = write_shards(rows, tmp, round(config.shard_mb * 2**20), schema)
    with staged_dir(run_previews_dir(run_dir, spec.scene_id)) as tmp:
        write_bytes(tmp / PREVIEW, png)
    by_task = _by_task(rows) if schema is TASK_SCHEMA else {}
    trajectories = sum(t for t, _ in by_task.values()) if schema is TASK_SCHEMA else len(vln.result.trajectories)
    return SceneEpisodes(spec.scene_id, out_dir, trajectories, len(rows),
                         [out_dir / p.name for p in shards],
                         llm, unreachable_rooms(smap), None if vln is None or vln.made.balance is None else
                         vln.made.balance.summary(), by_task)


def _by_task(rows: list[dict]) -> dict[str, tuple[int, int]]:
    """task -> (its trajectories, its rows), in the shards' order (vln first)."""
    tasks = dict.fromkeys(r["task"] for r in rows)
    return {t: (len({r["trajectory_id"] for r in rows if r["task"] == t}), sum(r["task"] == t for r in rows))
            for t in tasks}


def _llm_nogoal(tasks: dict[str, list[dict]], config: GenTrajectoriesConfig, vln: _VlnRows | None,
                api_key: str | None) -> tuple[dict[str, list[dict]], str | None]:
    """In llm mode, the task rows with each nogoal row's instruction a phrasing of SAGE's exploration instruction
    by the chat model (through the vln rows' client when there is one); and what the model gave (None in template
    mode)."""
    rows = tasks.get("nogoal") if config.instructions == "llm" else None
    notes = []
    if rows:
        from sagebench.instructions.exploration import exploration_instructions
        from sagebench.instructions.llm_client import ChatClient

        client = vln.instructor.client if vln and vln.instructor else ChatClient(config.llm, api_key=api_key)
        said = exploration_instructions(client, NOGOAL_INSTRUCTION, len(rows))
        tasks = {**tasks, "nogoal": [{**r, "instruction_text": text, "instruction_source": source}
                                     for r, (text, source) in zip(rows, said)]}
        llm = sum(source != "template" for _, source in said)
        notes.append(f"nogoal: {llm} of {len(rows)} instructions phrased by the model, {len(rows) - llm} "
                     "SAGE-Bench's sentence")
    if vln and vln.instructor:
        notes.insert(0, vln.instructor.summary())
    return tasks, "; ".join(notes) or None


@dataclass(frozen=True)
class _VlnRows:
    made: EpisodeRows
    result: SamplingResult
    instructor: LLMInstructor | None


def _vln_rows(scene_dir: Path, spec: SceneSpec, smap: SemanticMap, grid: GridMap, occupancy: np.ndarray,
              config: GenTrajectoriesConfig, api_key: str | None) -> _VlnRows:
    """The vln task: A* trajectories between named targets, instructed."""
    ctx = scene_context(spec, smap, config.high_level_mix)
    if config.instructions == "llm":
        ctx = replace(ctx, sight=scene_sight(smap, grid, occupancy))
    targets, names = scene_targets(spec, smap, ctx)
    result = sample_trajectories(grid, targets, spec.scene_id, config)
    _warn_if_short(spec.scene_id, result, config, n_targets=len(targets), scene_dir=scene_dir)
    instructor = None
    if config.instructions == "llm":
        from sagebench.instructions.llm import with_instructor

        ctx, instructor = with_instructor(ctx, config.llm, api_key=api_key)
    blocked = BlockedMap(occupancy != 0, grid.resolution, grid.origin)
    made = episode_rows(spec.scene_id, result.trajectories, names, config, ctx, blocked)
    if instructor is not None:
        _check_share(instructor, config, spec.scene_id, scene_dir)
    return _VlnRows(made, result, instructor)


def read_scene_inputs(scene_dir: Path) -> tuple[SceneSpec, SemanticMap, GridMap, np.ndarray]:
    """The normalised spec, semantic map, navigable grid and occupancy [H, W] uint8 of one built scene."""
    require(CONTRACT["gen_trajectories"].reads, scene_dir.parent.parent, scene_dir.name)
    spec_path, smap_path, npz_path = scene_dir / SCENE_FILE, scene_dir / SEMANTIC_MAP, scene_dir / TOPDOWN
    spec = parse_spec(spec_path.read_text(encoding="utf-8"), spec_path)
    smap = read_semantic_map(smap_path)
    grids = read_topdown_grids(npz_path)
    grid = GridMap(grids.navigable, grids.resolution, grids.origin, float(spec.floor_height), grids.anchors)
    return spec, smap, grid, grids.occupancy


def _check_share(instructor: LLMInstructor, config: GenTrajectoriesConfig, scene_id: str, scene_dir: Path) -> None:
    """A ServiceError (nothing written) when fewer high-level rows than `llm.min_share` came from the model; a
    warning with the instructor's summary when some fell back to the template."""
    share = instructor.share()
    if not share.enough:
        why = "no high-level row came from the model" if share.llm == 0 else \
            f"fewer high-level rows from the model than --llm-min-share {config.llm.min_share:g}"
        raise ServiceError(f"--instructions llm: {why} ({instructor.summary()}); nothing written (--llm-min-share 0 "
                           "keeps the template rows instead)", path=scene_dir)
    if instructor.stats["fallback"]:
        ui.warn(f"{scene_id}: {instructor.summary()}")


def _warn_if_short(scene_id: str, result: SamplingResult, config: GenTrajectoriesConfig, *, n_targets: int,
                   scene_dir: Path) -> None:
    """Warn when fewer trajectories than asked for were found, saying why; none at all is a DataError (nothing to
    write: a scene without a trajectory is a failed scene, not an empty success)."""
    got = len(result.trajectories)
    if got >= config.per_scene:
        return
    why = ", ".join(f"{n} {reason}" for reason, n in result.rejected.items()) or "no rejections"
    unreachable = f"; {len(result.unreachable_targets)} targets have no navigable cell within " \
                  f"{config.approach_max_m} m" if result.unreachable_targets else ""
    found = (f"{got} of {config.per_scene} trajectories: all {result.pairs_tried} ordered pairs of {n_targets} uniquely "
             f"named targets tried ({why}){unreachable}")
    if got == 0:
        raise DataError(f"no trajectory, nothing written: {found}", path=scene_dir)
    ui.warn(f"{scene_id}: {found}")
