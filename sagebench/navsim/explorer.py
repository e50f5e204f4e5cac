"""`explorer`: the no-goal baseline, a coverage explorer on the scene's navigable map (privileged: it reads the map
and its pose, as the oracle reads the reference path).

It keeps the floor its body has swept (`metrics/coverage.py`, the agent's radius) and walks, by the planner's
graph, to the main-region cell not yet swept (at least a forward step away) that is cheapest to reach in actions:
forward steps along the path plus the turns to face it, so it sweeps lanes straight ahead rather than zigzag to the
nearest scrap. It turns towards the path's next cell and moves forward as the oracle does, plans again at the
route's end or after a move more than half blocked, and stops when nothing reachable is left; the simulator ends
its episode at the episode's budget, as any agent's (sagebench/tasks/budget.py).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from scipy.sparse.csgraph import dijkstra

from sagebench.episodes.episode import Episode
from sagebench.metrics.coverage import swept_cells
from sagebench.metrics.on_foot import NavigableMap
from sagebench.navsim.actions import Action
from sagebench.navsim.policies import heading_action
from sagebench.settings.shared import ActionConfig


class Explorer:
    def __init__(self, maps: Callable[[str], NavigableMap], actions: ActionConfig = ActionConfig()):
        self.maps, self.actions = maps, actions

    def begin(self, episodes: Sequence[Episode]) -> None:
        self.navmaps = [self.maps(e.scene_id) for e in episodes]
        self.swept = [np.zeros(m.navigable.shape, dtype=bool) for m in self.navmaps]
        self.route: list[list[np.ndarray]] = [[] for _ in episodes]
        self.last: list[np.ndarray | None] = [None] * len(episodes)

    def act(self, slots, observations, infos) -> list:
        out = []
        for i, obs, info in zip(slots, observations, infos):
            pose = np.asarray(obs["pose"], dtype=np.float64)
            self._sweep(i, pose)
            stuck = info.get("collision_intensity", 0.0) > 0.5
            if stuck:
                self._plan(i, pose)
            while self.route[i] and np.hypot(*(self.route[i][0] - pose[:2])) <= self.actions.forward_step / 2:
                self.route[i].pop(0)
            if not self.route[i]:
                self._plan(i, pose)
            if not self.route[i]:
                out.append(Action.STOP)
                continue
            out.append(heading_action(pose, self.route[i][0], math.radians(self.actions.turn_deg)))
        return out

    def _sweep(self, i: int, pose: np.ndarray) -> None:
        m = self.navmaps[i]
        path = np.array([pose[:2] if self.last[i] is None else self.last[i], pose[:2]])
        self.swept[i] |= swept_cells(path, m.navigable.shape, m.resolution, m.origin, m.snap_radius)
        self.last[i] = pose[:2].copy()

    def _plan(self, i: int, pose: np.ndarray) -> None:
        """Route to the nearest unswept main-region cell at least a forward step away (none: an empty route)."""
        m = self.navmaps[i]
        self.route[i] = []
        cell = m.snap(pose[None, :2])[0]
        if cell[0] < 0:
            return
        h, w = m.navigable.shape
        dist, pred = dijkstra(m.graph(), directed=True, indices=int(cell[0] * w + cell[1]), return_predecessors=True)
        dist = dist.reshape(h, w) * m.resolution
        left = m.main_region & ~self.swept[i] & np.isfinite(dist) & (dist >= self.actions.forward_step)
        if not left.any():
            return
        rows, cols = np.indices((h, w))
        bearing = np.arctan2((rows + 0.5) * m.resolution + m.origin[1] - pose[1],
                             (cols + 0.5) * m.resolution + m.origin[0] - pose[0]) - pose[3]
        turns = np.abs(np.remainder(bearing + np.pi, 2 * np.pi) - np.pi) / math.radians(self.actions.turn_deg)
        actions = dist / self.actions.forward_step + turns
        goal = int(np.argmin(np.where(left, actions, np.inf)))
        chain = [goal]
        while pred[chain[-1]] >= 0:
            chain.append(int(pred[chain[-1]]))
        cells = np.array(chain[::-1][1:])
        centres = np.column_stack([cells % w + 0.5, cells // w + 0.5]) * m.resolution + np.asarray(m.origin)
        every = max(1, int(round(self.actions.forward_step / m.resolution)))
        self.route[i] = [*centres[every - 1::every], centres[-1]]
