"""One episode row as scoring and the closed loop use it: task, start, goal, reference path, level, type, split,
instruction and the goal fields of its task (episodes/tasks.py, docs/tasks.md)."""

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
    task: str = "vln"  # vln, nogoal, objectnav, pointnav or imagenav
    budget_s: float | None = None  # nogoal: time budget, s
    budget_steps: int | None = None  # nogoal: step budget
    goal_category: str | None = None  # objectnav: the category; any of goal_instance_ids counts
    goal_instance_ids: tuple[int, ...] = ()  # objectnav
    goal_viewpoints: np.ndarray | None = None  # objectnav: [K, 3] navigable cell centres within goal_radius of one
    goal_polar: tuple[float, float] | None = None  # pointnav: (rho, phi) from the start pose, habitat's PointGoal
    goal_yaw: float | None = None  # imagenav: goal camera heading, rad
    goal_image: str | None = None  # imagenav: "render:x,y,yaw" (rendered on demand) or a run-relative image path

    @property
    def has_goal(self) -> bool:
        """False for nogoal: its goal_position is its start and no distance decides its success."""
        return self.task != "nogoal"
