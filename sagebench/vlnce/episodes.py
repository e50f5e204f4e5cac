"""Episode rows -> habitat VLN episodes (R2R / VLN-CE dataset files), positions in habitat's frame.

A dataset file is gzipped JSON {"episodes": [...], "instruction_vocab": {...}}, each episode with the
fields habitat-lab's VLNEpisode takes: episode_id (str), trajectory_id (int), scene_id (path of the scene
GLB relative to the scenes directory), start_position [x, y, z], start_rotation [x, y, z, w], goals
[{position, radius}], info {geodesic_distance, ...}, instruction {instruction_text, instruction_tokens},
reference_path [[x, y, z], ...].
"""

from __future__ import annotations

import gzip
import json
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from sagebench.vlnce.frame import to_habitat, yaw_to_rotation
from sagebench.vlnce.vocab import Vocabulary

TRAJECTORY_HEX_DIGITS = 13  # trajectory_id's leading hex digits as habitat's int id (52 bits: exact in JSON)


def scene_glb_path(scene_id: str) -> str:
    """An episode's scene_id: the scene GLB relative to the export's scenes/ directory."""
    return f"{scene_id}/{scene_id}.glb"


def trajectory_number(trajectory_id: str) -> int:
    """habitat's integer trajectory id from sagebench's hex trajectory_id (stable, same path -> same int)."""
    return int(trajectory_id[:TRAJECTORY_HEX_DIGITS], 16)


def habitat_episode(row: Mapping[str, Any], vocab: Vocabulary) -> dict[str, Any]:
    """One episode row (the Parquet columns) as a habitat VLN episode."""
    path = np.asarray(row["reference_path"], dtype=np.float64).reshape(-1, 4)
    text = row["instruction_text"] or ""
    return {
        "episode_id": row["episode_id"],
        "trajectory_id": trajectory_number(row["trajectory_id"]),
        "scene_id": scene_glb_path(row["scene_id"]),
        "start_position": _floats(to_habitat(row["start_position"])),
        "start_rotation": yaw_to_rotation(float(row["start_yaw"])),
        "goals": [{"position": _floats(to_habitat(row["goal_position"])), "radius": float(row["goal_radius"])}],
        "info": {"geodesic_distance": float(row["geodesic_distance"]), "instruction_level": row["instruction_level"],
                 "instruction_type": row["instruction_type"], "sagebench_trajectory_id": row["trajectory_id"]},
        "instruction": {"instruction_text": text, "instruction_tokens": vocab.encode(text)},
        "reference_path": [_floats(p) for p in to_habitat(path[:, :3])],
    }


def dataset_bytes(rows: Sequence[Mapping[str, Any]], vocab: Vocabulary) -> bytes:
    """The gzipped dataset file of `rows` (in their order); byte-identical for the same rows."""
    data = {"episodes": [habitat_episode(r, vocab) for r in rows], "instruction_vocab": vocab.to_json()}
    text = json.dumps(data, sort_keys=True, separators=(",", ":")).encode()
    return gzip.compress(text, mtime=0)


def _floats(v) -> list[float]:
    return [float(x) for x in np.asarray(v, dtype=np.float64).reshape(-1)]
