"""`GENERATORS[mode]` lists, in order, the generators a `--instructions` mode runs on each trajectory; each takes
a `TrajectoryText` and a seeded generator and returns `Instruction`s. Both instruction modes write the two
low-level types and one high-level instruction; "llm" asks a chat model for the high-level one and falls back to
the template when the answer is not grounded.

Its own module, not the package's __init__: a reader of one helper (validate's `execution.BlockedMap`) would
otherwise import every generator and their libraries (scipy, shapely).
"""

from __future__ import annotations

import numpy as np

from sagebench.instructions import high_level, llm, low_level
from sagebench.instructions.base import Generator, Instruction, TrajectoryText

GENERATORS: dict[str, list[Generator]] = {
    "template": [low_level.base_action, low_level.single_goal, high_level.high_level],
    "llm": [low_level.base_action, low_level.single_goal, llm.llm_high_level],
    "none": [],
}


def instructions_for(text: TrajectoryText, mode: str, rng: np.random.Generator) -> list[Instruction]:
    """Every instruction `mode`'s generators write for one trajectory, in registry order."""
    return [ins for gen in GENERATORS[mode] for ins in gen(text, rng)]
