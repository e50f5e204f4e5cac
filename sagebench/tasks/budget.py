"""A no-goal episode's budget in actions, which the closed loop holds every agent to: the smaller of its
`budget_steps` and the whole actions its `budget_s` allows at the control interval (SAGE-Bench's 80 s are 160
actions of 0.5 s). The simulator ends the episode after that many actions, as the budget's end (`budget`,
truncated in gymnasium's terms), whatever the agent; goal tasks have no budget (their limit is --max-steps)."""

from __future__ import annotations

import math

from sagebench.episodes.episode import Episode

_EPS = 1e-9  # 80 s / 0.5 s is 160 actions, not 159 by rounding


def step_budget(episode: Episode, control_interval: float) -> int | None:
    """The actions a nogoal episode may take (module docstring); None for a goal task or an episode without a
    budget."""
    if episode.task != "nogoal":
        return None
    limits = [] if episode.budget_steps is None else [int(episode.budget_steps)]
    if episode.budget_s is not None:
        limits.append(math.floor(episode.budget_s / control_interval + _EPS))
    return min(limits, default=None)
