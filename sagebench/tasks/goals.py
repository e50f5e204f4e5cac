"""An episode's goal on its scene's map, by its task: the field of distances on foot that both the closed loop's
success and the scores read (one geometry, so success and the distance to the goal never disagree).

- vln, pointnav, imagenav: the distance on foot to the goal point (`goal_position`); success within goal_radius.
- objectnav: the distance on foot to the nearest goal viewpoint (every navigable cell within goal_radius of any
  instance of the category, `goal_viewpoints`); success within `viewpoint_tolerance` of one (habitat's 0.1 m).
- nogoal: no goal, no field: success is coverage's (`metrics/exploration.py`), never a distance test.
"""

from __future__ import annotations

import numpy as np

from sagebench.episodes.episode import Episode
from sagebench.metrics.on_foot import GoalField, NavigableMap, ViewpointField
from sagebench.settings.shared import TaskMetricConfig

GOAL_TASKS = ("objectnav", "pointnav", "imagenav")


def goal_field(navmap: NavigableMap, episode: Episode) -> GoalField | ViewpointField | None:
    """The distances on foot that decide the episode's success (None for nogoal)."""
    if not episode.has_goal:
        return None
    if episode.task == "objectnav":
        return navmap.viewpoint_field(viewpoint_cells(navmap, episode.goal_viewpoints))
    return navmap.field(episode.goal)


def viewpoint_cells(navmap: NavigableMap, viewpoints: np.ndarray) -> np.ndarray:
    """[H, W] bool: the cells holding the viewpoints [K, >=2] (world m) that lie on the map."""
    cells = navmap.cell_of(np.asarray(viewpoints, dtype=np.float64).reshape(-1, np.shape(viewpoints)[-1]))
    h, w = navmap.navigable.shape
    inside = (cells[:, 0] >= 0) & (cells[:, 0] < h) & (cells[:, 1] >= 0) & (cells[:, 1] < w)
    out = np.zeros((h, w), dtype=bool)
    out[cells[inside, 0], cells[inside, 1]] = True
    return out


def success_distance(episode: Episode, config: TaskMetricConfig = TaskMetricConfig()) -> float:
    """How near the goal (on foot, by `goal_field`) the agent must stop: objectnav's viewpoint tolerance, else the
    episode's goal_radius (nogoal has none: 0, never used)."""
    if episode.task == "objectnav":
        return config.viewpoint_tolerance
    return episode.goal_radius if episode.has_goal else 0.0
