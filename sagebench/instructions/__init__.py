"""Instructions for trajectories: generators registered per `--instructions` mode.

`GENERATORS[mode]` lists, in order, the generators a mode runs on each trajectory; each takes a
`TrajectoryText` and a seeded generator and returns `Instruction`s. A high-level generator (issue 5)
registers itself in the "template" list beside the low-level ones, and an "llm" mode is one more key.
"""

from __future__ import annotations

import numpy as np

from sagebench.instructions import low_level
from sagebench.instructions.base import Generator, Instruction, TrajectoryText

GENERATORS: dict[str, list[Generator]] = {
    "template": [low_level.base_action, low_level.single_goal],
    "none": [],
}


def instructions_for(text: TrajectoryText, mode: str, rng: np.random.Generator) -> list[Instruction]:
    """Every instruction `mode`'s generators write for one trajectory, in registry order."""
    return [ins for gen in GENERATORS[mode] for ins in gen(text, rng)]
