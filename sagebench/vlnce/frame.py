"""sagebench's world frame (Z up, yaw CCW from +X) to habitat's (Y up, the agent looking along -Z) and back.

habitat's scenes are Y up: a Z-up point (x, y, z) is (x, z, -y) there, the inverse of the turn the scene
loader applies to a Y-up input scene. An agent with identity rotation looks along habitat's -Z, which is
world +Y; its rotation is a turn about habitat's +Y, stored as a quaternion [x, y, z, w].
"""

from __future__ import annotations

import math

import numpy as np

# habitat (x, y, z) = HABITAT_FROM_WORLD @ world (x, y, z): a -90 degree turn about X
HABITAT_FROM_WORLD = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def to_habitat(points: np.ndarray) -> np.ndarray:
    """[..., 3] world points (Z up, metres) -> [..., 3] habitat points (Y up)."""
    return np.asarray(points, dtype=np.float64) @ HABITAT_FROM_WORLD.T


def from_habitat(points: np.ndarray) -> np.ndarray:
    """[..., 3] habitat points (Y up) -> [..., 3] world points (Z up)."""
    return np.asarray(points, dtype=np.float64) @ HABITAT_FROM_WORLD


def yaw_to_rotation(yaw: float) -> list[float]:
    """habitat's agent rotation [x, y, z, w] for a world heading `yaw` (radians CCW from +X): a turn of
    yaw - pi/2 about habitat's +Y (the agent's forward -Z is world +Y at yaw pi/2)."""
    half = (yaw - math.pi / 2) / 2
    return [0.0, math.sin(half), 0.0, math.cos(half)]


def rotation_to_yaw(rotation: list[float]) -> float:
    """The world yaw in (-pi, pi] of a habitat rotation [x, y, z, w] about +Y (inverse of yaw_to_rotation)."""
    x, y, z, w = rotation
    turn = 2 * math.atan2(y, w)
    return math.remainder(turn + math.pi / 2, 2 * math.pi)
