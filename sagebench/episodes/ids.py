"""The stable id of an episode row, declared once (episodes.rows and the SAGE episode import both make rows)."""

from __future__ import annotations

import hashlib


def episode_id(trajectory_id: str, level: str, kind: str, index: int) -> str:
    """Stable: the trajectory's id, the instruction's level and type, and its index among those of that type."""
    return hashlib.sha256(f"{trajectory_id}|{level}|{kind}|{index}".encode()).hexdigest()[:16]
