"""One episode row as scoring and the closed loop use it: start, goal, reference path, level, type, split and
instruction."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

NO_LEVEL = "none"  # group of rows without instruction_level/type (gen-trajectories --instructions none)


@dataclass(frozen=True)
class Episode:
    """What scoring needs of one episode row (metres, radians)."""

    episode_id: str
    scene_id: str
    level: str  # instruction_level, or NO_LEVEL
    type: str  # instruction_type, or NO_LEVEL
    start: np.ndarray  # [3]
    start_yaw: float
    goal: np.ndarray  # [3]
    goal_radius: float
    geodesic_distance: float
    reference_path: np.ndarray  # [M, 4] x, y, z, yaw
    split: str = NO_LEVEL  # train / val_seen / val_unseen / test; NO_LEVEL for runs made before splits
    instruction: str = ""  # instruction_text ("" for a bare trajectory): the caption of the episode's picture
