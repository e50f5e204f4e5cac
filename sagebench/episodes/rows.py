"""Episode rows: one per (trajectory, instruction), with stable ids, the high-level types balanced over a scene
and the benchmark split of each trajectory."""

from __future__ import annotations

import zlib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np

from sagebench import ui
from sagebench.astar.sampling import Trajectory
from sagebench.episodes.ids import episode_id
from sagebench.episodes.splits import assign_splits, instruction_held_out
from sagebench.instructions.registry import instructions_for
from sagebench.instructions.balance import TypeBalance
from sagebench.instructions.base import SceneContext, TrajectoryText
from sagebench.instructions.execution import BlockedMap
from sagebench.instructions.high_level import balanced
from sagebench.settings.gen_trajectories import GenTrajectoriesConfig


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
    trajectories are instructed on the client's concurrency of threads and the rows still come out in order.
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
        pool = ThreadPoolExecutor(ctx.llm.client.concurrency if ctx is not None and ctx.llm is not None else 1)
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
    held = instruction_held_out(split_of, config.splits)
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
            rows.append({**base, "episode_id": episode_id(traj.trajectory_id, "none", "", 0),
                         "instruction_level": None, "instruction_type": None, "instruction_text": None,
                         "instruction_source": None})
        counts: dict[tuple[str, str], int] = {}
        for ins in instructions:
            k = counts[(ins.level, ins.type)] = counts.get((ins.level, ins.type), -1) + 1
            rows.append({**base, "episode_id": episode_id(traj.trajectory_id, ins.level, ins.type, k),
                         "instruction_level": ins.level, "instruction_type": ins.type,
                         "instruction_text": ins.text, "instruction_source": ins.source,
                         **({"split": "instruction_unseen"} if traj.trajectory_id in held and ins.level == "high"
                            else {})})
    return EpisodeRows(rows, balance)
