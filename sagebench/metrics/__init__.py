"""Navigation (NE, SR, OSR, SPL, nDTW, SDTW) and continuity (CSR, ICP, PS) metrics, as docs/metrics.md defines them."""

from sagebench.metrics.episode import EpisodeMetrics, score_episode
from sagebench.metrics.on_foot import GoalField, NavigableMap, distance_on_foot

__all__ = ["EpisodeMetrics", "GoalField", "NavigableMap", "distance_on_foot", "score_episode"]
