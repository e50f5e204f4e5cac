"""Pinhole cameras: intrinsics plus a world-to-camera transform, and the agent's camera at a pose.

Camera frame as in OpenCV and the reference 3DGS rasterisers: x right, y down, z forward (depth).
Pixel (row i, col j) has its centre at image coordinates (u, v) = (j + 0.5, i + 0.5); a point
(x, y, z) in the camera frame lands at u = fx x / z + cx, v = fy y / z + cy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sagebench.settings.shared import CameraConfig


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
    camera_height: float = CameraConfig().height,
    pitch_deg: float = 0.0,
    hfov_deg: float = CameraConfig().hfov_deg,
    width: int = 640,
    height: int = 480,
) -> Camera:
    """The agent's camera: at (x, y, floor_z + camera_height), looking along `yaw` (radians, CCW from +X),
    tilted up by `pitch_deg` (negative looks down), Z up, square pixels (height and field of view default to
    CameraConfig's, declared there only)."""
    return agent_cameras(np.array([[x, y, yaw]], dtype=np.float64), floor_z=floor_z, camera_height=camera_height,
                         pitch_deg=pitch_deg, hfov_deg=hfov_deg, width=width, height=height)[0]


def agent_cameras(poses: np.ndarray, *, floor_z: float = 0.0, camera_height: float = CameraConfig().height,
                  pitch_deg: float = 0.0, hfov_deg: float = CameraConfig().hfov_deg, width: int = 640,
                  height: int = 480) -> list[Camera]:
    """`agent_camera` at each pose [B, >=3] (x, y, ..., yaw last) in one go. Sines and cosines come from `math`
    (libm, as for one camera; numpy's vectorised ones may differ in the last bit)."""
    poses = np.atleast_2d(np.asarray(poses, dtype=np.float64))
    pitch = math.radians(pitch_deg)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cos = np.array([math.cos(v) for v in poses[:, -1].tolist()])
    sin = np.array([math.sin(v) for v in poses[:, -1].tolist()])
    zero = np.zeros(len(poses))
    forward = np.stack([cos * cp, sin * cp, zero + sp], axis=1)
    right = np.stack([sin, -cos, zero], axis=1)
    down = np.cross(forward, right)
    rotations = np.stack([right, down, forward], axis=2)  # each [3, 3] C-ordered, as np.column_stack makes it
    positions = np.stack([poses[:, 0], poses[:, 1], zero + (floor_z + camera_height)], axis=1)
    # one camera at a time from here: a stacked matmul may round the translation differently from one camera's
    return [look_camera(p, r, width=width, height=height, hfov_deg=hfov_deg) for p, r in zip(positions, rotations)]
