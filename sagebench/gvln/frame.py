"""SAGE-3D's 3D frame for GVLN trajectories, and its heading quaternion, against sagebench's world frame.

SAGE-3D plans on a 2D semantic map that is the world turned by 180 degrees (semantic_map_builder.py draws a box's
cell (i, j) at (H-1-i, W-1-j)), then moves each point into its 3D frame by mirroring x and y about the map's
bounds and negating both (trajectory_2d_to_3d.py): a translation, so the 3D frame is the world turned by 180
degrees about Z, where Data/template.usda also places the collision payload (orient (0, 0, 0, 1) about Z). So a
world point (x, y) is (-x, -y) in SAGE's file, and a heading yaw is yaw + pi there; on an InteriorGS scene, where
SAGE's tools mirror about its mask cells' bounds rounded to 2 decimals, (ox - x, oy - y), (ox, oy) the scene's
`sage_offset` (sagebench.importers.sage_frame; within 1 cm of 0).

Its rotation is stored as [qx, qy, qz, qw] = [-sin(psi / 2), 0, 0, cos(psi / 2)] with psi = the 3D heading + pi
(the 2D heading plus pi, "put qz to qx and negate"); simple_env.py reads the heading back as
2 * atan2(-qx, qw) - pi. The two turns by pi cancel: psi is the heading in sagebench's world frame. The last point
of a trajectory has the identity rotation (trajectory_2d_to_3d.py resets it). Heights: SAGE-3D writes z = 0.5
(its trajectory generator's FIXED_Z) and keeps its camera at 1.2 m; sagebench writes floor + SAGE_Z and reads
positions onto its floor.
"""

from __future__ import annotations

import math

import numpy as np

SAGE_Z = 0.5  # m above the floor: SAGE-3D's FIXED_Z for trajectory points


def wrap(angle: float) -> float:
    """An angle in radians, in (-pi, pi]."""
    a = math.remainder(angle, 2 * math.pi)
    return math.pi if a == -math.pi else a


def to_sage_xy(xy: np.ndarray, offset: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """[..., 2] world xy -> SAGE-3D's 3D-frame xy (turned by 180 degrees about Z, then moved by the scene's
    `offset`); the map is its own inverse."""
    return np.asarray(offset, dtype=np.float64) - np.asarray(xy, dtype=np.float64)


def sage_rotation(yaw: float) -> list[float]:
    """[qx, qy, qz, qw] SAGE-3D stores for a world heading `yaw` (radians, CCW from +x)."""
    psi = wrap(yaw)
    return [-math.sin(psi / 2), 0.0, 0.0, math.cos(psi / 2)]


def yaw_from_sage_rotation(q: list[float]) -> float:
    """The world heading of a SAGE-3D 3D-frame rotation [qx, qy, qz, qw] (simple_env.py's reading, plus pi)."""
    qx, _, _, qw = (float(v) for v in q)
    return wrap(2 * math.atan2(-qx, qw))

