"""The training data in NaVILA's layout, as NaVILA's own trainer reads it (AnjieCheng/NaVILA: llava/data/dataset.py
LazyVLNCEDataset, evaluation/vlnce_baselines/navila_trainer.py): frames as image files, and samples that pair every
step's frames so far with the next action in NaVILA's words.

DIR/navila/images/<scene_id>/images/trajectory_<episode_id>/frame_NNNNN.png   one file per step's view
DIR/navila/annotations_<split>.json   one per split, a list (LazyVLNCEDataset's `data_path` loads one file):
                                      {"video_id": "<scene_id>_<episode_id>-<step>", "q": instruction,
                                      "a": "The next action is move forward 25 cm.", "frames": [the episode's frames
                                      from step 0 to this step, relative to images/ (its `image_path`)]}
DIR/navila/dataset_info.json          per split its data_path, image_path and samples; the action wording

The answers are what navila_trainer.py parses: the action by "stop" / "is move forward" / "is turn left" / "is
turn right", then the amount by `move forward (\\d+) cm` and `turn left|right (\\d+) degree`, whole centimetres and
degrees; it executes 25, 50 or 75 cm and 15, 30 or 45 degrees (others are snapped to the nearest), so an export
whose step or turn is none of those is refused rather than trained on amounts its evaluator would not execute.
"""

from __future__ import annotations

import json
import tarfile
from collections.abc import Iterator
from pathlib import Path

from sagebench.errors import ConfigError
from sagebench.fileio import dumps_json, staged_dir, write_bytes, write_text
from sagebench.settings.shared import ActionConfig

NAVILA_DIR = "navila"
IMAGES = "images"
STEPS_CM = (25, 50, 75)  # the moves navila_trainer.py executes (0.25 m actions, 1 to 3 of them)
TURNS_DEG = (15, 30, 45)  # its turns (15-degree actions, 1 to 3 of them)


def action_words(config: ActionConfig) -> dict[str, str]:
    """Each action in NaVILA's words with this export's step and turn; a ConfigError when NaVILA's evaluator would
    not execute them as written."""
    cm, deg = config.forward_step * 100, config.turn_deg
    if round(cm) != cm or round(cm) not in STEPS_CM or round(deg) != deg or round(deg) not in TURNS_DEG:
        raise ConfigError(f"NaVILA's evaluator executes moves of {', '.join(map(str, STEPS_CM))} cm and turns of "
                          f"{', '.join(map(str, TURNS_DEG))} degrees; this export's are {config.forward_step:g} m and "
                          f"{deg:g} degrees", field="--navila")
    return {"STOP": "stop", "MOVE_FORWARD": f"move forward {round(cm)} cm",
            "TURN_LEFT": f"turn left {round(deg)} degrees", "TURN_RIGHT": f"turn right {round(deg)} degrees"}


def _episodes(shard: Path) -> Iterator[tuple[dict, list[bytes]]]:
    """(the first sample's meta with every step's action, each step's RGB PNG) per episode of one shard."""
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


def _samples(tmp: Path, shard: Path, words: dict[str, str]) -> list[dict]:
    """The samples of one shard's episodes, their frames written under tmp/images."""
    samples = []
    for meta, frames in _episodes(shard):
        rel = [f"{meta['scene_id']}/images/trajectory_{meta['episode_id']}/frame_{k:05d}.png"
               for k in range(len(frames))]
        for path, png in zip(rel, frames):
            write_bytes(tmp / IMAGES / path, png)
        video = f"{meta['scene_id']}_{meta['episode_id']}"
        samples += [{"video_id": f"{video}-{k}", "q": meta["instruction"], "a": f"The next action is {words[action]}.",
                     "frames": rel[: k + 1]} for k, action in enumerate(meta["actions"])]
    return samples


def write_navila(out: Path, shards: list[tuple[Path, str]], config: ActionConfig) -> int:
    """Write OUT/navila/ (module docstring) from the finished shards (path, split), whole; returns the number of
    samples."""
    words = action_words(config)
    by_split: dict[str, list[dict]] = {}
    with staged_dir(out / NAVILA_DIR) as tmp:
        for shard, split in shards:
            by_split.setdefault(split, []).extend(_samples(tmp, shard, words))
        for split, samples in by_split.items():
            write_text(tmp / f"annotations_{split}.json", dumps_json(samples))
        write_text(tmp / "dataset_info.json", dumps_json({
            "dataset_name": "sagebench_NaVILA", "dataset_type": "vlnce",
            "total_samples": sum(len(s) for s in by_split.values()),
            "splits": {split: {"data_path": f"annotations_{split}.json", "image_path": IMAGES, "samples": len(s)}
                       for split, s in by_split.items()},
            "data_format": {"answer": "The next action is {action}.", "actions": words}}))
    return sum(len(s) for s in by_split.values())
