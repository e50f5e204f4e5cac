"""Imitation-learning data from a run: each episode's reference path as discrete actions (actions.py), executed in
the simulator, every step's view (RGB, optionally depth) with its action label and the instruction, written as
WebDataset tar shards (shards.py).

Sample k of an episode is the view the agent has before its k-th action and that action: view 0 is the start,
view k (k > 0) what the simulator rendered after action k - 1, collisions included; the last sample's action is
STOP. An episode the simulator ends early (it left the map) keeps the samples up to there. Only vln episodes are
exported (an instruction to follow); the other tasks' episodes are left out and counted (docs/tasks.md).

Layout of OUT: `export.json` (settings and a hash of the inputs, written first: a later export into OUT must match
it), `shards/<split>-NNNNNN.tar` (EPISODES_PER_SHARD episodes each, in run order), then `index.json` (shards,
samples, episodes) and, when asked, NaVILA's layout made from the shards (navila.py). A shard is written whole or not at all, so an export killed at any moment resumes at the
first missing shard and ends with the same bytes.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable
from collections import Counter
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from sagebench import __version__
from sagebench.episodes.load import load_episodes
from sagebench.episodes.preview import png_bytes
from sagebench.episodes.tasks import VLN
from sagebench.errors import ConfigError, DataError
from sagebench.fileio import dumps_json, remove_temporaries, write_text
from sagebench.navsim.actions import Action
from sagebench.navsim.simulator import Simulator
from sagebench.render.backends import choose_backend
from sagebench.run_layout import (
    COLLIDERS, COLLIDERS_INDEX, GAUSSIANS, MJCF, SHARDS, TOPDOWN, run_episodes_dir, run_scene_dir,
)
from sagebench.run_folder import claim_export_dir
from sagebench.settings.export_training import TrainingExportConfig
from sagebench.training.actions import path_actions
from sagebench.training.navila import action_words, write_navila
from sagebench.training.shards import chunks, depth_png, open_shard, sample_json, sample_key, shard_samples

SETTINGS_FILE = "export.json"
INDEX_FILE = "index.json"
SHARD_DIR = "shards"
FORMAT = "sagebench-training-webdataset/1"
NOT_IN_SHARDS = {"renderer", "batch", "workers", "navila"}  # recorded as the backend used, or not shaping the shards


@dataclass(frozen=True)
class TrainingExport:
    out: Path
    episodes: int
    samples: int
    shards: int
    written: int  # shards written by this call (the others were there from an earlier one)
    new_samples: int  # samples in the shards written by this call
    seconds: float
    renderer: str
    other_tasks: dict[str, int] = field(default_factory=dict)  # task -> its episodes left out (of the split asked)

    def summary(self) -> str:
        rate = self.new_samples / self.seconds if self.written and self.seconds > 0 else float("nan")
        line = (f"export-training: {self.episodes} episodes, {self.samples} frames in {self.shards} shards "
                f"({self.written} written now, {rate:.1f} frames/s, renderer {self.renderer}) -> {self.out}")
        return line + (f"\nleft out {_count(self.other_tasks)}: export-training writes VLN episodes only"
                       if self.other_tasks else "")


def export_training(run_dir: Path, out: Path, config: TrainingExportConfig = TrainingExportConfig(), *,
                    on_progress: Callable[[int, int], None] | None = None) -> TrainingExport:
    """Export every episode (or `config.split`'s) of the run into OUT (module docstring); `on_progress(episodes,
    frames)` as episodes finish (those of shards already there count at once)."""
    run_dir, out = Path(run_dir), Path(out)
    start = time.perf_counter()
    sim = Simulator(run_dir, config.env(), threads=config.workers)
    ids = [e for e in sim.order if config.split is None or sim.episodes[e].split == config.split]
    others = dict(sorted(Counter(e.task for e in load_episodes(run_dir) if e.task != VLN
                                 and config.split in (None, e.split)).items()))
    besides = f" (only {_count(others)})" if others else ""
    if not ids and config.split is None:
        raise DataError(f"no vln episodes to export{besides}", path=run_dir)
    if not ids:
        raise ConfigError(f"no episodes of split {config.split!r} in {run_dir}{besides}", field="--split")
    if config.navila:
        action_words(config.actions)  # refused before the first shard, not after the last
    backend = choose_backend(config.renderer, config.env().observations)
    settings = {"format": FORMAT, "sagebench": __version__, "renderer": backend,
                "config": config.model_dump(mode="json", exclude=NOT_IN_SHARDS),
                "inputs": _input_hashes(run_dir, sorted({sim.episodes[e].scene_id for e in ids}))}
    # one export per OUT (a second would remove the first's shard in progress), never inside the run
    with claim_export_dir(out, run_dir, "export-training", SETTINGS_FILE):
        done = _export_locked(sim, ids, out, settings, config, on_progress, start, backend)
    return replace(done, other_tasks=others)


def _count(by_task: dict[str, int]) -> str:
    """'12 episodes of tasks other than vln (nogoal 3, ...)'."""
    return (f"{sum(by_task.values())} episodes of tasks other than vln "
            f"({', '.join(f'{t} {n}' for t, n in by_task.items())})")


def _export_locked(sim: Simulator, ids: list[str], out: Path, settings: dict, config: TrainingExportConfig,
                   on_progress: Callable[[int, int], None] | None, start: float, backend: str) -> TrainingExport:
    _claim(out, settings)
    by_split: dict[str, list[str]] = {}
    for e in ids:
        by_split.setdefault(sim.episodes[e].split, []).append(e)
    plan = [(f"{split}-{k:06d}.tar", part) for split, group in by_split.items()
            for k, part in enumerate(chunks(group, config.episodes_per_shard))]
    shards, done, samples, written, new = [], 0, 0, 0, 0
    report = on_progress or (lambda episodes, frames: None)
    for name, part in plan:
        path = out / SHARD_DIR / name
        if path.is_file():
            count = shard_samples(path)
        else:
            count = _write_shard(sim, part, path, config, lambda n, k: report(done + n, samples + k))
            written, new = written + 1, new + count
        shards.append({"file": f"{SHARD_DIR}/{name}", "episodes": len(part), "samples": count,
                       "split": sim.episodes[part[0]].split})
        done, samples = done + len(part), samples + count
        report(done, samples)
    write_text(out / INDEX_FILE, dumps_json({**settings, "episodes": len(ids), "samples": samples, "shards": shards}))
    if config.navila:
        write_navila(out, [(out / s["file"], s["split"]) for s in shards], config.actions)
    return TrainingExport(out=out, episodes=len(ids), samples=samples, shards=len(plan), written=written,
                          new_samples=new, seconds=time.perf_counter() - start, renderer=backend)


def _claim(out: Path, settings: dict) -> None:
    """Make OUT (locked, and new or holding an export) this export's; an earlier call's export must have the same
    settings and inputs (then its half-written temporaries go and finished shards stay)."""
    path = out / SETTINGS_FILE
    if path.is_file():
        if json.loads(path.read_text(encoding="utf-8")) != settings:
            raise ConfigError(f"{out} holds an export of other settings or inputs; use a new --out or remove it",
                              field="--out")
        remove_temporaries([out / SHARD_DIR], entries_of=[out])
    write_text(path, dumps_json(settings))


def _input_hashes(run_dir: Path, scene_ids: list[str]) -> dict[str, str]:
    """sha256 of every run file the export reads (episode shards, Gaussians, map, MuJoCo model, collider index)."""
    files = []
    for sid in scene_ids:
        files += sorted(run_episodes_dir(run_dir, sid).glob(SHARDS))
        scene = run_scene_dir(run_dir, sid)
        files += [scene / GAUSSIANS, scene / TOPDOWN, scene / MJCF, scene / COLLIDERS / COLLIDERS_INDEX]
    out = {}
    for f in files:
        h = hashlib.sha256()
        with open(f, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
        out[f.relative_to(run_dir).as_posix()] = h.hexdigest()
    return out


def _write_shard(sim: Simulator, episode_ids: list[str], path: Path, config: TrainingExportConfig,
                 report: Callable[[int, int], None]) -> int:
    """Run these episodes, `config.batch` at a time, and write their samples to the shard at `path`;
    `report(episodes, samples)` of this shard after each batch."""
    with open_shard(path) as shard:
        for n, batch in enumerate(chunks(episode_ids, config.batch)):
            plans = [path_actions(sim.episodes[e].reference_path, sim.episodes[e].start_yaw, config.actions)
                     for e in batch]
            results = sim.start(batch)
            samples: list[list[dict[str, bytes]]] = [[] for _ in batch]  # written episode by episode
            step = 0
            while True:
                live = [i for i in range(len(batch)) if not sim.slots[i].done and step < len(plans[i])]
                if not live:
                    break
                for i in live:
                    samples[i].append(_sample(results[i], plans[i][step], step, sim, batch[i], config.depth))
                actions = [plans[i][step] if i in live else Action.STOP for i in range(len(batch))]
                results = sim.step(actions)
                step += 1
            for eid, files in zip(batch, samples):
                for k, sample in enumerate(files):
                    shard.add(sample_key(eid, k), sample)
            report(min((n + 1) * config.batch, len(episode_ids)), shard.samples)
        return shard.samples


def _sample(result, action: Action, step: int, sim: Simulator, episode_id: str, depth: bool) -> dict[str, bytes]:
    obs, info = result.observation, result.info
    e = sim.episodes[episode_id]
    meta = {"episode_id": episode_id, "scene_id": e.scene_id, "split": e.split, "step": step,
            "instruction": obs["instruction"], "action": int(action), "action_name": action.name,
            "pose": [float(v) for v in obs["pose"]], "collided": bool(obs["collided"]),
            "collision_intensity": float(info["collision_intensity"])}
    files = {"rgb.png": png_bytes(obs["rgb"]), "json": sample_json(meta)}
    if depth:
        files["depth.png"] = depth_png(obs["depth"])
    return files
