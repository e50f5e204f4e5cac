"""Polyline helpers in the XY plane: length, resampling at a fixed spacing, distance to a polyline."""

from __future__ import annotations

import numpy as np


def path_length(points: np.ndarray) -> float:
    """Sum of XY segment lengths.  points: [T, >=2] metres."""
    p = np.asarray(points, dtype=np.float64)[:, :2]
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) if len(p) > 1 else 0.0


def resample(points: np.ndarray, spacing: float) -> np.ndarray:
    """[M, 2] points every `spacing` metres along the XY polyline, first and last point included."""
    p = np.asarray(points, dtype=np.float64)[:, :2]
    if len(p) == 1:
        return p.copy()
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    total = s[-1]
    if total == 0.0:
        return p[:1].copy()
    stations = np.arange(0.0, total, spacing)
    if total - stations[-1] > 1e-9:
        stations = np.append(stations, total)
    return np.column_stack([np.interp(stations, s, p[:, 0]), np.interp(stations, s, p[:, 1])])


def distance_to_polyline(points: np.ndarray, polyline: np.ndarray) -> np.ndarray:
    """[T] XY distance from each point to the nearest point of the polyline.

    points: [T, >=2]; polyline: [M, >=2] (M = 1 means a single point).
    """
    q = np.asarray(points, dtype=np.float64)[:, None, :2]  # [T, 1, 2]
    v = np.asarray(polyline, dtype=np.float64)[:, :2]
    if len(v) == 1:
        return np.linalg.norm(q[:, 0] - v[0], axis=1)
    a, b = v[:-1][None], v[1:][None]  # [1, M-1, 2]
    ab = b - a
    denom = np.maximum((ab * ab).sum(-1), 1e-18)
    t = np.clip(((q - a) * ab).sum(-1) / denom, 0.0, 1.0)
    closest = a + t[..., None] * ab
    return np.linalg.norm(q - closest, axis=-1).min(axis=1)
