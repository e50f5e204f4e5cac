"""Pinhole cameras: intrinsics plus a world-to-camera transform, and the agent's camera at a pose.

Camera frame as in OpenCV and the reference 3DGS rasterisers: x right, y down, z forward (depth).
Pixel (row i, col j) has its centre at image coordinates (u, v) = (j + 0.5, i + 0.5); a point
(x, y, z) in the camera frame lands at u = fx x / z + cx, v = fy y / z + cy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Camera:
    """A pinhole camera; `world_to_camera` is [4, 4] float64 (rotation and translation, no scale)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    world_to_camera: np.ndarray

    def __post_init__(self) -> None:
        if self.width < 1 or self.height < 1:
            raise ValueError(f"image size must be positive, got {self.width}x{self.height}")
        if np.shape(self.world_to_camera) != (4, 4):
            raise ValueError(f"world_to_camera: expected (4, 4), got {np.shape(self.world_to_camera)}")

    @property
    def position(self) -> np.ndarray:
        """[3] camera centre in world coordinates."""
        rot, t = self.world_to_camera[:3, :3], self.world_to_camera[:3, 3]
        return -rot.T @ t

    def scaled(self, width: int, height: int) -> Camera:
        """The same view at another resolution (intrinsics scaled with the image)."""
        sx, sy = width / self.width, height / self.height
        return Camera(width, height, self.fx * sx, self.fy * sy, self.cx * sx, self.cy * sy, self.world_to_camera)


def look_camera(position: np.ndarray, rotation_cw: np.ndarray, *, width: int, height: int, hfov_deg: float) -> Camera:
    """A camera at `position` [3] whose axes (right, down, forward) are the columns of `rotation_cw` [3, 3]."""
    if not 0 < hfov_deg < 180:
        raise ValueError(f"hfov_deg must be in (0, 180), got {hfov_deg}")
    f = (width / 2) / math.tan(math.radians(hfov_deg) / 2)
    w2c = np.eye(4)
    w2c[:3, :3] = rotation_cw.T
    w2c[:3, 3] = -rotation_cw.T @ np.asarray(position, dtype=np.float64)
    return Camera(width, height, f, f, width / 2, height / 2, w2c)


def agent_camera(
    x: float,
    y: float,
    yaw: float,
    *,
    floor_z: float = 0.0,
    camera_height: float = 1.2,
    pitch_deg: float = 0.0,
    hfov_deg: float = 90.0,
    width: int = 640,
    height: int = 480,
) -> Camera:
    """The agent's camera: at (x, y, floor_z + camera_height), looking along `yaw` (radians, CCW from +X),
    tilted up by `pitch_deg` (negative looks down), Z up, square pixels."""
    pitch = math.radians(pitch_deg)
    forward = np.array([math.cos(yaw) * math.cos(pitch), math.sin(yaw) * math.cos(pitch), math.sin(pitch)])
    right = np.array([math.sin(yaw), -math.cos(yaw), 0.0])
    down = np.cross(forward, right)
    rot = np.column_stack([right, down, forward])
    return look_camera(np.array([x, y, floor_z + camera_height]), rot, width=width, height=height, hfov_deg=hfov_deg)
