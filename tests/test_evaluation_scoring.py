"""Scores per episode and their plain means overall, per instruction level and per type."""

from __future__ import annotations

import numpy as np
import pytest

from sagebench.episodes.episode import Episode
from sagebench.evaluation.predictions import Prediction
from sagebench.metrics import EpisodeMetrics
from sagebench.evaluation.scoring import (
    EpisodeScore, score_prediction, summarise_scores,
)


def _episode(eid: str, level: str = "low", kind: str = "Single_Goal") -> Episode:
    path = np.array([[0, 0, 0, 0], [4, 0, 0, 0]], float)
    return Episode(episode_id=eid, scene_id="s", level=level, type=kind, start=np.zeros(3), start_yaw=0.0,
                   goal=np.array([4.0, 0, 0]), goal_radius=1.0, geodesic_distance=4.0, reference_path=path)


def test_a_prediction_is_scored_with_its_intensity():
    e = _episode("a")
    p = Prediction(episode_id="a", poses=[(0, 0, 0, 0), (2, 0, 0, 0), (3.5, 0, 0, 0)], stopped=True,
                   collision_intensity=[0, 0.3, 0.0])
    m = score_prediction(e, p, np.asarray(p.collision_intensity), on_foot=None)
    assert m.sr == 1.0 and m.ne == pytest.approx(0.5) and m.spl == 1.0  # 3.5 m walked < 4 m geodesic
    assert m.icp == pytest.approx(0.1) and m.csr == 1.0 and m.ps == 1.0
    assert not score_prediction(e, p.model_copy(update={"stopped": False}), np.zeros(3), on_foot=None).sr


def test_means_overall_per_level_and_per_type():
    def score(eid, level, kind, sr, icp):
        m = EpisodeMetrics(ne=1.0, ne_straight=1.0, sr=sr, osr=sr, spl=sr, ndtw=0.5, sdtw=sr / 2, csr=1.0, icp=icp, ps=1.0,
                           path_length=2.0)
        return EpisodeScore(_episode(eid, level, kind), m, missing=False, icp_source="self-reported")

    s = summarise_scores([score("a", "low", "Base_Action", 1, 0.0), score("b", "low", "Single_Goal", 0, 0.3),
                          score("c", "high", "Area_Based", 1, 0.6)])
    assert s.overall["episodes"] == 3 and s.overall["sr"] == pytest.approx(2 / 3) and s.overall["icp"] == pytest.approx(0.3)
    assert list(s.by_level) == ["high", "low"]
    assert s.by_level["low"]["episodes"] == 2 and s.by_level["low"]["sr"] == 0.5 and s.by_level["low"]["icp"] == pytest.approx(0.15)
    assert list(s.by_type) == ["Area_Based", "Base_Action", "Single_Goal"]
    assert s.by_type["Area_Based"]["sdtw"] == 0.5 and s.by_type["Single_Goal"]["sr"] == 0.0
