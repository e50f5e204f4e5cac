"""The instruction record every generator returns, and what a generator may know about a trajectory."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

Level = Literal["high", "low"]


@dataclass(frozen=True)
class Instruction:
    level: Level
    type: str  # Base_Action, Single_Goal, Add_Object, ...
    text: str
    source: str  # "template" or "llm:<model>"


@dataclass(frozen=True)
class TrajectoryText:
    """What a generator may mention: the path's shape and the endpoints' unique names (never ids)."""

    waypoints: np.ndarray  # [M, 4] float64 (x, y, z, yaw), metres and radians
    start_name: str  # e.g. "the dining table", "the kitchen"
    goal_name: str
    start_kind: Literal["object", "room"]
    goal_kind: Literal["object", "room"]


Generator = Callable[[TrajectoryText, np.random.Generator], list[Instruction]]
