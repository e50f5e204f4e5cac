"""Navigation (NE, SR, OSR, SPL, nDTW, SDTW) and continuity (CSR, ICP, PS) metrics, as DESIGN.md defines them."""

from sagebench.metrics.episode import EpisodeMetrics, MetricConfig, score_episode

__all__ = ["EpisodeMetrics", "MetricConfig", "score_episode"]
