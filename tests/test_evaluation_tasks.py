"""Each episode is scored by its own task, whatever else is scored with it (SAGE-3D issue #18)."""

from __future__ import annotations

import numpy as np
import pytest

from sagebench.episodes.episode import Episode
from sagebench.evaluation.predictions import Prediction
from sagebench.evaluation.scoring import TASK_METRICS, score_episodes, summarise_scores
from sagebench.metrics.on_foot import NavigableMap

START = np.array([1.0, 1.0, 0.0])


def _map() -> NavigableMap:
    """Two 3 x 3 m rooms side by side, a door between them."""
    nav = np.ones((60, 120), dtype=bool)
    nav[:, 59:61] = False
    nav[25:35, 59:61] = True
    return NavigableMap(nav, 0.05, (0.0, 0.0), snap_radius=0.2)


def _episodes() -> list[Episode]:
    goal = np.array([5.0, 2.0, 0.0])
    path = np.array([[1.0, 1.0, 0, 0], [3.0, 1.5, 0, 0], [5.0, 2.0, 0, 0]])
    base = dict(scene_id="s", level="low", type="t", start=START, start_yaw=0.0, goal=goal, goal_radius=1.0,
                geodesic_distance=4.2, reference_path=path)
    viewpoints = np.array([[x, y, 0.0] for x in np.arange(4.525, 5.5, 0.05) for y in np.arange(1.525, 2.5, 0.05)])
    return [
        Episode(episode_id="vln", **base),
        Episode(episode_id="nogoal", task="nogoal", budget_s=80.0, budget_steps=160,
                **(base | {"goal": START, "goal_radius": 0.0, "geodesic_distance": 0.0,
                           "reference_path": path[:1]})),
        Episode(episode_id="objectnav", task="objectnav", goal_category="sofa", goal_instance_ids=(7,),
                goal_viewpoints=viewpoints, **base),
        Episode(episode_id="pointnav", task="pointnav", goal_polar=(4.1, 0.24), **(base | {"goal_radius": 0.2})),
        Episode(episode_id="imagenav", task="imagenav", goal_yaw=0.0, goal_image="render:5.0,2.0,0.0", **base),
    ]


def _stationary(eid: str) -> Prediction:
    return Prediction(episode_id=eid, poses=[tuple(START) + (0.0,)] * 40, stopped=True,
                      collision_intensity=[0.0] * 40)


def _scores(episodes, navmap):
    matched = {e.episode_id: _stationary(e.episode_id) for e in episodes}
    return {s.episode.episode_id: s for s in score_episodes(episodes, matched, {}, {"s": navmap})}


def test_a_stationary_agent_scores_sr_0_and_no_coverage_on_every_task_alone_and_batched():
    navmap, episodes = _map(), _episodes()
    batched = _scores(episodes, navmap)
    for e in episodes:
        alone = _scores([e], navmap)[e.episode_id]
        assert alone.metrics == batched[e.episode_id].metrics  # its score does not depend on the others
        assert alone.metrics.sr == 0.0, e.task
        assert set(alone.metrics.as_dict()) == set(TASK_METRICS[e.task])
    assert batched["nogoal"].metrics.coverage < 0.02


def test_each_task_gets_a_group_of_its_own_metrics_and_vln_groups_hold_vln_alone():
    navmap, episodes = _map(), _episodes()
    summary = summarise_scores(list(_scores(episodes, navmap).values()))
    assert list(summary.by_task) == ["vln", "nogoal", "objectnav", "pointnav", "imagenav"]
    assert summary.overall["episodes"] == 1 and summary.by_task["nogoal"]["coverage"] < 0.02
    assert all(d["sr"] == 0.0 and d["episodes"] == 1 for d in summary.by_task.values())
    assert not summary.tasks_only_vln


def test_objectnav_succeeds_on_a_viewpoint_and_pointnav_only_within_its_radius():
    navmap, episodes = _map(), {e.episode_id: e for e in _episodes()}
    walk = [(1.0, 1.0, 0, 0), (3.0, 1.3, 0, 0), (4.6, 1.6, 0, 0)]
    matched = {k: Prediction(episode_id=k, poses=walk, stopped=True) for k in ("objectnav", "pointnav")}
    s = {x.episode.episode_id: x.metrics for x in score_episodes(list(episodes.values())[2:4], matched,
                                                                 {k: np.zeros(3) for k in matched}, {"s": navmap})}
    assert s["objectnav"].sr == 1.0 and s["objectnav"].ne == 0.0
    assert s["pointnav"].sr == 0.0 and s["pointnav"].ne == pytest.approx(np.hypot(0.4, 0.4), abs=0.01)
