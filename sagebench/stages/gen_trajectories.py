"""`gen-trajectories`: A* episodes with low-level instructions, from build-scene's maps to Parquet shards.

Reads RUN/scenes/<scene_id>/{topdown.npz, semantic_map.json, scene.json}; writes
RUN/episodes/<scene_id>/part-<split>-NNNNN.parquet and _preview/paths.png, replacing the directory whole. The
preview sits in a "_" folder so that the directory reads as one Parquet dataset (pyarrow skips "_" names).
"""

from __future__ import annotations

import hashlib
import os
import zlib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import Field, ValidationError, model_validator
from shapely.geometry import Polygon

from sagebench import ui
from sagebench.astar.sampling import GridMap, SamplingConfig, SamplingResult, TargetSpec, Trajectory, sample_trajectories
from sagebench.episodes.preview import render_paths
from sagebench.episodes.shards import write_shards
from sagebench.episodes.splits import SplitConfig, assign_splits
from sagebench.config import from_options
from sagebench.errors import ConfigError, DataError, ServiceError, first_error
from sagebench.fileio import staged_dir, write_bytes
from sagebench.instructions import instructions_for
from sagebench.instructions.execution import BlockedMap
from sagebench.instructions.balance import TypeBalance
from sagebench.instructions.base import HIGH_LEVEL_TYPES, SceneContext, TrajectoryText, make_context
from sagebench.instructions.high_level import balanced
from sagebench.instructions.llm_client import API_KEY_ENV, LLMConfig, check_cache_dir, default_cache_dir
from sagebench.instructions.naming import ObjectInfo, RoomInfo
from sagebench.instructions.sight import SightMap, sight_map
from sagebench.run_layout import CONTRACT, PREVIEW, SCENE_FILE, SCENES, SEMANTIC_MAP, TOPDOWN, require, run_episodes_dir
from sagebench.scene.loader import parse_spec
from sagebench.scene.model import SceneSpec
from sagebench.topdown.grid_file import read_topdown_grids
from sagebench.topdown.semantic_map import SemanticMap

TARGET_KINDS = ("object", "door")  # what a trajectory may start or end at, besides rooms
FIXTURE_KINDS = ("window",)  # what else an instruction may mention


class GenTrajectoriesConfig(SamplingConfig):
    """Settings of gen-trajectories: sampling plus what is written (defaults here, nowhere else)."""

    shard_mb: float = Field(default=128.0, gt=0, description="Largest Parquet shard, MB (one split per shard).")
    instructions: Literal["template", "llm", "none"] = Field(
        default="template",
        description="template: Base_Action, Single_Goal and one high-level row per trajectory; llm: the high-level "
                    "row from a chat model (grounded, else the template); none: one bare row per trajectory.")
    high_level_mix: dict[Literal[HIGH_LEVEL_TYPES], float] = Field(  # type: ignore[valid-type]
        default={t: 1.0 for t in HIGH_LEVEL_TYPES},
        description="Relative share of each high-level type (a type that cannot describe a goal is skipped).")
    llm: LLMConfig = Field(default=LLMConfig(), description="Chat model for --instructions llm.")
    goal_radius_m: float = Field(
        default=1.0, gt=0,
        description="Success radius, m: the stand point is ~0.2-0.3 m from the target, so 1 m means next to it.")
    preview_paths: int = Field(default=40, ge=0, description="Paths drawn in paths.png.")
    splits: SplitConfig = Field(default=SplitConfig(), description="Split fractions and seed (episodes/splits.py).")

    @model_validator(mode="after")
    def _instruction_settings(self) -> GenTrajectoriesConfig:
        if any(v < 0 for v in self.high_level_mix.values()) or not any(v > 0 for v in self.high_level_mix.values()):
            raise ValueError("high_level_mix needs non-negative shares, at least one positive")
        if self.instructions == "llm" and not (self.llm.base_url and self.llm.model):
            raise ValueError("--instructions llm needs --llm-base-url and --llm-model")
        if self.instructions != "llm" and self.llm != LLMConfig():
            raise ValueError("--llm-* options (the llm table) are used only with --instructions llm")
        return self


def make_config(**fields: object) -> GenTrajectoriesConfig:
    """A config from the options given (None = keep the default); a bad value is a ConfigError naming the option.

    An --llm-* option without --instructions llm is an error even when it repeats the default.
    """
    llm = fields.get("llm") or {}
    if isinstance(llm, dict) and llm and fields.get("instructions") != "llm":
        option = {path: opt for opt, path in OPTIONS.items()}[f"llm.{next(iter(llm))}"]
        raise ConfigError("used only with --instructions llm", field=option)
    return from_options(GenTrajectoriesConfig, fields, OPTIONS)


# gen-trajectories' options and the GenTrajectoriesConfig fields they set (their defaults and error names come from here)
OPTIONS = {"--per-scene": "per_scene", "--seed": "seed", "--shard-mb": "shard_mb", "--instructions": "instructions",
           "--min-geodesic": "min_geodesic_m", "--max-geodesic": "max_geodesic_m", "--goal-radius": "goal_radius_m",
           "--llm-base-url": "llm.base_url", "--llm-model": "llm.model", "--llm-cache-dir": "llm.cache_dir",
           "--llm-concurrency": "llm.concurrency", "--llm-timeout": "llm.timeout_s", "--llm-attempts": "llm.max_attempts",
           "--llm-temperature": "llm.temperature", "--llm-max-tokens": "llm.max_tokens",
           "--llm-min-share": "llm.min_share"}


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

    def summary(self) -> str:
        line = (f"gen-trajectories {self.scene_id}: {self.trajectories} trajectories, {self.rows} episode rows "
                f"in {len(self.shards)} shard(s) -> {self.out_dir}")
        if self.unreachable_rooms:
            line += (f"\n  left out (unreachable: most of the navigable floor outside the main region): rooms "
                     f"{', '.join(self.unreachable_rooms)} and the objects in them")
        if self.high_level_summary is not None:
            line += f"\n  high-level types: {self.high_level_summary}"
        return line if self.llm_summary is None else f"{line}\n  llm: {self.llm_summary}"


def gen_trajectories(run_dir: Path, config: GenTrajectoriesConfig, *, scene_id: str | None = None,
                     api_key: str | None = None) -> list[SceneEpisodes]:
    """Sample, instruct and write the episodes of every scene in RUN_DIR/scenes (or only `scene_id`).

    api_key: the LLM bearer token (default: the environment variable SAGEBENCH_LLM_API_KEY, never another).
    """
    scenes_root = Path(run_dir) / SCENES
    if not scenes_root.is_dir():
        raise DataError("no scenes/ directory: run build-scene on this run directory first", path=run_dir)
    if scene_id is not None:
        if not (scenes_root / scene_id).is_dir():
            known = ", ".join(sorted(p.name for p in scenes_root.iterdir() if p.is_dir())) or "none"
            raise ConfigError(f"no scene {scene_id!r} in {scenes_root} (scenes: {known})", field="--scene")
        scene_dirs = [scenes_root / scene_id]
    else:
        scene_dirs = sorted(p for p in scenes_root.iterdir() if p.is_dir() and not p.name.startswith("."))
        if not scene_dirs:
            raise DataError("no scene directories: run build-scene first", path=scenes_root)
    if config.instructions == "llm":
        cache_dir = config.llm.cache_dir or default_cache_dir()
        problem = check_cache_dir(Path(cache_dir))
        if problem is not None:
            raise ConfigError(problem, path=cache_dir, field="--llm-cache-dir")
    key = os.environ.get(API_KEY_ENV) if api_key is None else api_key
    return [generate_scene(d, run_episodes_dir(run_dir, d.name), config, api_key=key)
            for d in ui.track(scene_dirs, "gen-trajectories")]


def generate_scene(scene_dir: Path, out_dir: Path, config: GenTrajectoriesConfig, *,
                   api_key: str | None = None) -> SceneEpisodes:
    """One scene: read its maps, sample trajectories, write shards and the paths preview into `out_dir` (replaced).

    In llm mode, a scene whose high-level rows come from the model less often than `llm.min_share`
    (or never) is a ServiceError and nothing is written.
    """
    spec, smap, grid, occupancy = read_scene_inputs(scene_dir)
    ctx = scene_context(spec, smap, config.high_level_mix)
    if config.instructions == "llm":
        ctx = replace(ctx, sight=scene_sight(smap, grid, occupancy))
    targets, names = scene_targets(spec, smap, ctx)
    result = sample_trajectories(grid, targets, spec.scene_id, config)
    _warn_if_short(spec.scene_id, result, config, n_targets=len(targets))
    instructor = None
    if config.instructions == "llm":
        from sagebench.instructions.llm import with_instructor

        ctx, instructor = with_instructor(ctx, config.llm, api_key=api_key)
    blocked = BlockedMap(occupancy != 0, grid.resolution, grid.origin)
    made = episode_rows(spec.scene_id, result.trajectories, names, config, ctx, blocked)
    rows = made.rows
    if instructor is not None:
        share = instructor.share()
        if not share.enough:
            why = "no high-level row came from the model" if share.llm == 0 else \
                f"fewer high-level rows from the model than --llm-min-share {config.llm.min_share:g}"
            raise ServiceError(f"--instructions llm: {why} ({instructor.summary()}); nothing written", path=scene_dir)
        if instructor.stats["fallback"]:
            ui.warn(f"{spec.scene_id}: {instructor.summary()}")
    with staged_dir(out_dir) as tmp:
        shards = write_shards(rows, tmp, round(config.shard_mb * 2**20))
        png = render_paths(grid.navigable, occupancy, [t.waypoints for t in result.trajectories[:config.preview_paths]],
                           grid.resolution, grid.origin)
        write_bytes(tmp / PREVIEW, png)
    return SceneEpisodes(spec.scene_id, out_dir, len(result.trajectories), len(rows),
                         [out_dir / p.name for p in shards], None if instructor is None else instructor.summary(),
                         unreachable_rooms(smap), None if made.balance is None else made.balance.summary())


def read_scene_inputs(scene_dir: Path) -> tuple[SceneSpec, SemanticMap, GridMap, np.ndarray]:
    """The normalised spec, semantic map, navigable grid and occupancy [H, W] uint8 of one built scene."""
    require(CONTRACT["gen_trajectories"].reads, scene_dir.parent.parent, scene_dir.name)
    spec_path, smap_path, npz_path = scene_dir / SCENE_FILE, scene_dir / SEMANTIC_MAP, scene_dir / TOPDOWN
    spec = parse_spec(spec_path.read_text(encoding="utf-8"), spec_path)
    try:
        smap = SemanticMap.model_validate_json(smap_path.read_bytes())
    except ValidationError as err:
        loc, msg, _ = first_error(err)
        raise DataError(msg, path=smap_path, field=loc) from None
    grids = read_topdown_grids(npz_path)
    grid = GridMap(grids.navigable, grids.resolution, grids.origin, float(spec.floor_height), grids.anchors)
    return spec, smap, grid, grids.occupancy


def scene_context(spec: SceneSpec, smap: SemanticMap, type_mix: dict[str, float] | None = None) -> SceneContext:
    """Objects, rooms, unique names (relations allowed) and footprints of one scene, for naming and instructions.

    Objects and doors are what trajectories start and end at; an object's attributes are its scene.json
    attributes plus its door state. Footprints of things above the agent's band (ceiling lamps) are left
    out, so they serve as no landmark.
    """
    attrs = {o.instance_id: dict(o.attributes) for o in spec.objects}
    top = smap.floor_height + smap.band_m[1]

    def info(i) -> ObjectInfo:
        return ObjectInfo(i.instance_id, i.category, i.room,
                          {**attrs.get(i.instance_id, {}), **({"state": i.door_state} if i.door_state else {})})

    objects = [info(i) for i in smap.instances if i.kind in TARGET_KINDS]
    fixtures = [info(i) for i in smap.instances if i.kind in FIXTURE_KINDS]
    footprints = {i.instance_id: [np.asarray(p[0], dtype=np.float64) for p in i.polygon.coordinates]
                  for i in smap.instances if i.kind in TARGET_KINDS and i.min_z <= top and i.polygon.coordinates}
    return make_context(objects, [RoomInfo(r.id, r.type) for r in spec.rooms],
                        {r.id: np.asarray(r.polygon, dtype=np.float64) for r in spec.rooms}, footprints,
                        fixtures=fixtures, doors={i.instance_id for i in smap.instances if i.kind == "door"},
                        type_mix=type_mix)


def scene_sight(smap: SemanticMap, grid: GridMap, occupancy: np.ndarray) -> SightMap:
    """The cells that block the view: blocked cells inside a wall's or a closed door's footprint."""
    blockers = [Polygon(p[0], p[1:]) for i in smap.instances
                if i.kind == "wall" or (i.kind == "door" and i.door_state == "closed") for p in i.polygon.coordinates]
    return sight_map(occupancy, grid.resolution, grid.origin, blockers)


def scene_targets(spec: SceneSpec, smap: SemanticMap,
                  ctx: SceneContext | None = None) -> tuple[list[TargetSpec], dict[str, str]]:
    """Targets that can be named uniquely, and target key -> referring expression.

    Objects and doors standing in the agent's height band (not ceiling lamps) and rooms, except unreachable
    rooms and what is in them (`unreachable_rooms`).
    """
    ctx = scene_context(spec, smap) if ctx is None else ctx
    top = smap.floor_height + smap.band_m[1]
    cut_off = set(unreachable_rooms(smap))
    targets: list[TargetSpec] = []
    names: dict[str, str] = {}
    for inst in smap.instances:
        if (inst.kind not in TARGET_KINDS or inst.instance_id not in ctx.names or inst.min_z > top
                or not inst.polygon.coordinates or inst.room in cut_off):
            continue
        key = f"object:{inst.instance_id}"
        outlines = tuple(np.asarray(poly[0], dtype=np.float64) for poly in inst.polygon.coordinates)
        targets.append(TargetSpec(key, "object", inst.instance_id, inst.room, outlines))
        names[key] = ctx.names[inst.instance_id]
    for room in spec.rooms:
        if room.id in ctx.room_names and room.id not in cut_off:
            key = f"room:{room.id}"
            targets.append(TargetSpec(key, "room", None, room.id, (np.asarray(room.polygon, dtype=np.float64),)))
            names[key] = ctx.room_names[room.id]
    return targets, names


def unreachable_rooms(smap: SemanticMap) -> tuple[str, ...]:
    """Rooms build-scene found unreachable (most of their navigable floor outside the main region)."""
    return tuple(r.room_id for r in smap.rooms if not r.reachable)


@dataclass(frozen=True)
class EpisodeRows:
    rows: list[dict[str, Any]]
    balance: TypeBalance | None  # the high-level types chosen for the trajectories (None without instructions)


def episode_rows(scene_id: str, trajectories: list[Trajectory], names: dict[str, str],
                 config: GenTrajectoriesConfig, ctx: SceneContext | None = None,
                 blocked: BlockedMap | None = None) -> EpisodeRows:
    """One row per (trajectory, instruction); one bare row per trajectory when instructions are 'none'.

    `blocked` (the occupancy map) is what Base_Action's literal execution must not cross. The high-level
    types are chosen for all trajectories at once (`high_level.balanced`, seeded by (seed, scene id)), so
    their counts follow `config.high_level_mix` wherever the goals allow.

    Each trajectory's wording depends only on (seed, trajectory id) and its chosen type, so in llm mode
    trajectories are instructed on `config.llm.concurrency` threads and the rows still come out in order.
    """
    texts = [TrajectoryText(t.waypoints, names[t.start.key], names[t.goal.key], t.start.kind, t.goal.kind,
                            t.start.instance_id, t.goal.instance_id, t.start_room, t.goal_room, ctx,
                            config.goal_radius_m, blocked) for t in trajectories]
    balance = None
    if config.instructions != "none":
        phrasing = [np.random.default_rng([config.seed, int(t.trajectory_id, 16), 1]) for t in trajectories]
        choice = np.random.default_rng([config.seed, zlib.crc32(f"high-level types|{scene_id}".encode())])
        texts, balance = balanced(texts, phrasing, choice)

    def instruct(item: tuple[Trajectory, TrajectoryText]):
        traj, text = item
        rng = np.random.default_rng([config.seed, int(traj.trajectory_id, 16)])
        return instructions_for(text, config.instructions, rng)

    items = list(zip(trajectories, texts, strict=True))
    if config.instructions == "llm":
        pool = ThreadPoolExecutor(config.llm.concurrency)
        try:
            instructed = list(ui.track(pool.map(instruct, items), "instructions (llm)", len(items)))
        except BaseException:  # Ctrl-C: cut the requests in flight and leave without waiting for the queue
            if ctx is not None and ctx.llm is not None:
                ctx.llm.client.cancel()
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown()
    else:
        instructed = [instruct(item) for item in items]
    split_of = assign_splits(scene_id, [t.trajectory_id for t in trajectories], config.splits)
    rows = []
    for traj, instructions in zip(trajectories, instructed, strict=True):
        wps = traj.waypoints
        base = {
            "trajectory_id": traj.trajectory_id,
            "scene_id": scene_id,
            "start_instance_id": traj.start.instance_id,
            "goal_instance_id": traj.goal.instance_id,
            "start_room": traj.start_room,
            "goal_room": traj.goal_room,
            "start_position": wps[0, :3].tolist(),
            "start_yaw": float(wps[0, 3]),
            "goal_position": wps[-1, :3].tolist(),
            "goal_radius": config.goal_radius_m,
            "reference_path": wps.tolist(),
            "geodesic_distance": traj.path_length_m,
            "seed": config.seed,
            "split": split_of[traj.trajectory_id],
        }
        if not instructions:
            rows.append({**base, "episode_id": _episode_id(traj.trajectory_id, "none", "", 0),
                         "instruction_level": None, "instruction_type": None, "instruction_text": None,
                         "instruction_source": None})
        counts: dict[tuple[str, str], int] = {}
        for ins in instructions:
            k = counts[(ins.level, ins.type)] = counts.get((ins.level, ins.type), -1) + 1
            rows.append({**base, "episode_id": _episode_id(traj.trajectory_id, ins.level, ins.type, k),
                         "instruction_level": ins.level, "instruction_type": ins.type,
                         "instruction_text": ins.text, "instruction_source": ins.source})
    return EpisodeRows(rows, balance)


def _episode_id(trajectory_id: str, level: str, kind: str, index: int) -> str:
    """Stable: the trajectory's id, the instruction's level and type, and its index among those of that type."""
    return hashlib.sha256(f"{trajectory_id}|{level}|{kind}|{index}".encode()).hexdigest()[:16]


def _warn_if_short(scene_id: str, result: SamplingResult, config: GenTrajectoriesConfig, *, n_targets: int) -> None:
    got = len(result.trajectories)
    if got >= config.per_scene:
        return
    why = ", ".join(f"{n} {reason}" for reason, n in result.rejected.items()) or "no rejections"
    unreachable = f"; {len(result.unreachable_targets)} targets have no navigable cell within " \
                  f"{config.approach_max_m} m" if result.unreachable_targets else ""
    ui.warn(f"{scene_id}: {got} of {config.per_scene} trajectories: all {result.pairs_tried} ordered pairs of "
            f"{n_targets} uniquely named targets tried ({why}){unreachable}")
