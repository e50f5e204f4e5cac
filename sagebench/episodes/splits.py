"""Benchmark splits (R2R / SAGE-Bench style): unseen splits hold whole scenes, seen splits share scenes with train.

A scene goes to `val_unseen` or `test` by a hash of (seed, scene_id) against the configured scene fractions, so a
scene's split depends on nothing else: adding scenes to a run, or building them in another order or on more
workers, never moves another scene (the realised scene fractions approach the configured ones as scenes grow).
Every other scene is seen: its trajectories are ranked by a hash of (seed, trajectory_id) and the first
round(n * val_seen) go to `val_seen`, the next round(n * trajectory_unseen) to `trajectory_unseen`, the rest to
`train`. All rows of one trajectory share its split, so a path seen in training is never scored in validation under
another wording, with one exception asked for by name: `instruction_unseen` takes the high-level row of a share
of the train trajectories (ranked by another hash), whose other rows stay in train, a seen path with a held-out
phrasing.

SAGE-Bench's test splits are `test` (Scene-Unseen), `trajectory_unseen` and `instruction_unseen`
(settings.shared.SAGE_SPLITS); both shares default to 0, which leaves every split as before they existed.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence

from sagebench.settings.gen_trajectories import SplitConfig
from sagebench.settings.shared import Split


def _unit(seed: int, key: str) -> float:
    """A number in [0, 1) fixed by (seed, key)."""
    digest = hashlib.sha256(f"{seed}\0{key}".encode()).digest()
    return int.from_bytes(digest[:8], "big") / 2.0**64


def scene_split(scene_id: str, config: SplitConfig) -> Split | None:
    """`val_unseen` or `test` for a held-out scene, None for a seen one."""
    u = _unit(config.seed, "scene\0" + scene_id)
    if u < config.val_unseen:
        return "val_unseen"
    if u < config.val_unseen + config.test:
        return "test"
    return None


def assign_splits(scene_id: str, trajectory_ids: Sequence[str], config: SplitConfig) -> dict[str, Split]:
    """The split of every trajectory of one scene (module docstring)."""
    held_out = scene_split(scene_id, config)
    if held_out is not None:
        return {t: held_out for t in trajectory_ids}
    ranked = sorted(set(trajectory_ids), key=lambda t: (_unit(config.seed, "trajectory\0" + t), t))
    n_val = round(len(ranked) * config.val_seen)
    n_held = n_val + round(len(ranked) * config.trajectory_unseen)
    return {t: ("val_seen" if i < n_val else "trajectory_unseen" if i < n_held else "train")
            for i, t in enumerate(ranked)}


def instruction_held_out(split_of: dict[str, Split], config: SplitConfig) -> set[str]:
    """The train trajectories whose high-level row goes to `instruction_unseen`: the first
    round(n * instruction_unseen) of them ranked by a hash of (seed, trajectory_id)."""
    train = sorted((t for t, s in split_of.items() if s == "train"),
                   key=lambda t: (_unit(config.seed, "phrasing\0" + t), t))
    return set(train[:round(len(train) * config.instruction_unseen)])
