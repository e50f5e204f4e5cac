"""The training shards in NaVILA's layout, as SAGE-3D's `create_navila_dataset.py` builds it for NaVILA: frames as
image files, and samples that pair every step's frames so far with the next action in words.

DIR/navila/images/<scene_id>/images/trajectory_<episode_id>/frame_NNNNN.png   one file per step's view
DIR/navila/annotations_part_NNN.json   lists of {"video_id": "<scene_id>_<episode_id>-<step>", "q": instruction,
                                       "a": "The next action is move forward 0.25 meter.", "frames": [the episode's
                                       frames from step 0 to this step, relative to images/]}, SAMPLES_PER_PART each
DIR/navila/dataset_info.json           totals, part files and the action wording
"""

from __future__ import annotations

import json
import math
import tarfile
from collections.abc import Iterator
from pathlib import Path

from sagebench.fileio import dumps_json, staged_dir, write_bytes, write_text
from sagebench.settings.shared import ActionConfig

SAMPLES_PER_PART = 10000  # create_navila_dataset.py's default
NAVILA_DIR = "navila"


def action_words(config: ActionConfig) -> dict[str, str]:
    """Each action in NaVILA's wording, with this export's step and turn."""
    step, turn = f"{config.forward_step:g}", f"{config.turn_deg:g}"
    return {"STOP": "stop", "MOVE_FORWARD": f"move forward {step} meter", "TURN_LEFT": f"turn left {turn} degree",
            "TURN_RIGHT": f"turn right {turn} degree"}


def _episodes(shards: list[Path]) -> Iterator[tuple[dict, list[bytes]]]:
    """(the first sample's meta with every step's action, each step's RGB PNG) per episode, in shard order."""
    for shard in shards:
        with tarfile.open(shard) as tar:
            members = {m.name: m for m in tar.getmembers()}
            keys = sorted({name.split(".", 1)[0] for name in members})
            current, actions, frames = None, [], []
            for key in keys:
                meta = json.loads(tar.extractfile(members[f"{key}.json"]).read())
                if current is not None and meta["episode_id"] != current["episode_id"]:
                    yield {**current, "actions": actions}, frames
                    actions, frames = [], []
                if not actions:
                    current = meta
                actions.append(meta["action_name"])
                frames.append(tar.extractfile(members[f"{key}.rgb.png"]).read())
            if current is not None:
                yield {**current, "actions": actions}, frames


def write_navila(out: Path, shards: list[Path], config: ActionConfig) -> int:
    """Write OUT/navila/ (module docstring) from the finished shards, whole; returns the number of samples."""
    words = action_words(config)
    samples = []
    with staged_dir(out / NAVILA_DIR) as tmp:
        for meta, frames in _episodes(shards):
            rel = [f"{meta['scene_id']}/images/trajectory_{meta['episode_id']}/frame_{k:05d}.png"
                   for k in range(len(frames))]
            for path, png in zip(rel, frames):
                write_bytes(tmp / "images" / path, png)
            video = f"{meta['scene_id']}_{meta['episode_id']}"
            samples += [{"video_id": f"{video}-{k}", "q": meta["instruction"],
                         "a": f"The next action is {words[action]}.", "frames": rel[: k + 1]}
                        for k, action in enumerate(meta["actions"])]
        parts = []
        for k in range(math.ceil(len(samples) / SAMPLES_PER_PART)):
            name = f"annotations_part_{k:03d}.json"
            write_text(tmp / name, dumps_json(samples[k * SAMPLES_PER_PART: (k + 1) * SAMPLES_PER_PART]))
            parts.append(name)
        write_text(tmp / "dataset_info.json", dumps_json({
            "dataset_name": "sagebench_NaVILA", "total_samples": len(samples), "num_parts": len(parts),
            "samples_per_part": SAMPLES_PER_PART, "part_files": parts,
            "data_format": {"move_distance": f"{config.forward_step:g} meter", "turn_angle": f"{config.turn_deg:g} degree",
                            "action_format": "The next action is {action}."}}))
    return len(samples)
