"""Rolling a policy out over a run's episodes in the simulator: batches of episodes stepped together until every
episode ends, the predictions in episode order, and a few episodes' views kept for a contact sheet.

Episodes never influence each other (simulator.py), and policies keep per-episode state, so predictions do not
depend on the batch size or the thread count.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from sagebench.evaluation.predictions import Prediction
from sagebench.navsim.policies import Policy
from sagebench.navsim.simulator import Simulator

SHEET_FRAMES = 64  # frames kept per sheet episode (every 2^k-th), enough to pick its middle


@dataclass
class Views:
    """Sampled RGB views of one episode: frames at steps 0, s, 2s, ... (s doubles to keep at most SHEET_FRAMES)
    and the last one."""

    episode_id: str
    frames: list[np.ndarray] = field(default_factory=list)
    stride: int = 1
    last: np.ndarray | None = None
    steps: int = 0

    def add(self, step: int, rgb: np.ndarray) -> None:
        self.last, self.steps = rgb, step
        if step % self.stride == 0:
            self.frames.append(rgb)
            if len(self.frames) > SHEET_FRAMES:
                self.frames, self.stride = self.frames[::2], self.stride * 2

    def start_middle_end(self) -> list[np.ndarray]:
        return [self.frames[0], self.frames[len(self.frames) // 2], self.last]


@dataclass(frozen=True)
class RolloutResult:
    predictions: list[Prediction]
    views: list[Views]
    steps: int  # actions taken over all episodes


def rollout(sim: Simulator, policy: Policy, episode_ids: Sequence[str], *, batch: int = 8, sheet: int = 4,
            on_step: Callable[[int, int], None] | None = None) -> RolloutResult:
    """Run `policy` on every episode of `episode_ids`, `batch` at a time; keep the views of the first `sheet`
    episodes (when RGB is rendered). `on_step(episodes_done, steps)` after every step."""
    predictions, views, steps, done = [], [], 0, 0
    keep_rgb = "rgb" in sim.config.observations
    for first in range(0, len(episode_ids), max(1, batch)):
        ids = list(episode_ids[first: first + batch])
        results = sim.start(ids)
        policy.begin([s.episode for s in sim.slots])
        mine = {i: Views(eid) for i, eid in enumerate(ids) if keep_rgb and first + i < sheet}
        for i, v in mine.items():
            v.add(0, results[i].observation["rgb"])
        while True:
            running = [i for i, s in enumerate(sim.slots) if not s.done]
            if not running:
                break
            actions = policy.act(running, [results[i].observation for i in running], [results[i].info for i in running])
            full: list = [0] * len(sim.slots)
            for i, a in zip(running, actions):
                full[i] = a
            results = sim.step(full)
            moved = [i for i in running if sim.slots[i].steps > 0 and sim.slots[i].outcome != "stop"]
            steps += len(running)
            for i in moved:
                if i in mine:
                    mine[i].add(sim.slots[i].steps, results[i].observation["rgb"])
            done_now = sum(s.done for s in sim.slots)
            if on_step:
                on_step(done + done_now, steps)
        done += len(ids)
        predictions += [s.prediction() for s in sim.slots]
        views += [mine[i] for i in sorted(mine)]
    return RolloutResult(predictions=predictions, views=views, steps=steps)


def contact_sheet(views: Sequence[Views], *, label_height: int = 18) -> np.ndarray:
    """[H, W, 3] uint8 RGB: one row per episode (start, middle, end), the episode id above each row."""
    rows = []
    for v in views:
        frames = v.start_middle_end()
        h, w = frames[0].shape[:2]
        strip = np.concatenate(frames, axis=1)
        label = np.full((label_height, strip.shape[1], 3), 255, np.uint8)
        text = f"{v.episode_id}: start | middle | end (step {v.steps})"
        cv2.putText(label, text, (4, label_height - 5), cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 1, cv2.LINE_AA)
        rows.append(np.concatenate([label, strip], axis=0))
    return np.concatenate(rows, axis=0)
