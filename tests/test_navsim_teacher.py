"""The oracle's teacher path (VLN-CE's gt actions) on known paths, and the gt file's entry."""

from __future__ import annotations

import gzip
import json
import math

import numpy as np

from sagebench.evaluation.scoring import Episode
from sagebench.navsim.teacher import teacher_path
from sagebench.vlnce.gt import gt_bytes, gt_entry


def episode(path, yaw: float) -> Episode:
    p = np.array([[*q, 0.0] for q in path], dtype=np.float64)
    return Episode("e", "s", "low", "Base_Action", p[0, :3], yaw, p[-1, :3], 1.0, 0.0, p)


def test_a_straight_metre_is_four_moves_then_stop():
    path = teacher_path(episode([(0, 0, 0), (1, 0, 0)], yaw=0.0))
    assert path.actions == (1, 1, 1, 1, 0)
    assert np.allclose(path.positions[:, 0], [0, 0.25, 0.5, 0.75, 1.0, 1.0])


def test_a_left_corner_is_six_15_degree_turns():
    path = teacher_path(episode([(0, 0, 0), (0.5, 0, 0), (0.5, 1.0, 0)], yaw=0.0))
    assert path.actions == (1, 1, 2, 2, 2, 2, 2, 2, 1, 1, 1, 1, 0)
    assert np.allclose(path.positions[-1], (0.5, 1.0, 0.0), atol=1e-9)


def test_facing_away_it_turns_round_first():
    path = teacher_path(episode([(0, 0, 0), (0.5, 0, 0)], yaw=math.pi))
    assert path.actions[:12] == (2,) * 12 or path.actions[:12] == (3,) * 12
    assert path.actions[12:] == (1, 1, 0)


def test_gt_entry_keeps_one_location_per_move_in_habitat_frame():
    path = teacher_path(episode([(0, 0, 0), (0.5, 0, 0), (0.5, 1.0, 0)], yaw=0.0))
    entry = gt_entry(path.actions, path.positions)
    assert entry["forward_steps"] == 6 and len(entry["locations"]) == 7 and entry["actions"][-1] == 0
    assert np.allclose(entry["locations"][-1], [0.5, 0.0, -1.0])  # world (x, y, z) is habitat (x, z, -y)
    data = json.loads(gzip.decompress(gt_bytes({"e": entry})))
    assert data == {"e": entry} and gt_bytes({"e": entry}) == gt_bytes({"e": entry})
