"""Rolling a policy out over a run's episodes in the simulator: batches of episodes stepped together until every
episode ends, each finished episode handed on as it ends, the predictions in episode order, episodes the policy
failed set aside, and a few episodes' views kept for a contact sheet.

Episodes never influence each other (simulator.py), and policies keep per-episode state, so predictions do not
depend on the batch size or the thread count.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np

from sagebench.errors import ConfigError
from sagebench.evaluation.predictions import Prediction
from sagebench.episodes.episode import Episode
from sagebench.navsim.policies import Policy, PolicyFailure
from sagebench.navsim.simulator import Simulator
from sagebench.settings.shared import SPLITS

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
        """Keep a copy of the step's view (an observation's images are rows of the step's batch arrays)."""
        rgb = np.array(rgb)
        self.last, self.steps = rgb, step
        if step % self.stride == 0:
            self.frames.append(rgb)
            if len(self.frames) > SHEET_FRAMES:
                self.frames, self.stride = self.frames[::2], self.stride * 2

    def start_middle_end(self) -> list[np.ndarray]:
        return [self.frames[0], self.frames[len(self.frames) // 2], self.last]


@dataclass(frozen=True)
class RolloutResult:
    predictions: list[Prediction]  # the finished episodes, in the order of episode_ids
    views: list[Views]  # of the `sheet` episodes that finished
    steps: int  # actions taken over all episodes
    failed: list[tuple[str, str]] = field(default_factory=list)  # (episode id, why) of episodes the policy failed
    stopped_early: bool = False  # more than max_failures episodes failed: the rest were not run


def rollout(sim: Simulator, policy: Policy, episode_ids: Sequence[str], *, batch: int = 8,
            sheet: Sequence[str] | int = 4, on_step: Callable[[int, int], None] | None = None,
            on_finish: Callable[[Prediction], None] | None = None, max_failures: int | None = None) -> RolloutResult:
    """Run `policy` on every episode of `episode_ids`, `batch` at a time; keep the views of the `sheet` episodes
    (ids, or the first that many; when RGB is rendered). `on_step(episodes_done, steps)` after every step,
    `on_finish(prediction)` as each episode ends. A slot the policy answers with a PolicyFailure ends there, failed
    by the policy (not a prediction); after more than `max_failures` such episodes the rollout stops."""
    finished: dict[str, Prediction] = {}
    views, failed, steps, done = [], [], 0, 0
    keep = set(episode_ids[:sheet]) if isinstance(sheet, int) else set(sheet)
    keep_rgb = "rgb" in sim.sensors.images
    for first in range(0, len(episode_ids), max(1, batch)):
        ids = list(episode_ids[first: first + batch])
        results = sim.start(ids)
        policy.begin([s.episode for s in sim.slots])
        mine = {i: Views(eid) for i, eid in enumerate(ids) if keep_rgb and eid in keep}
        for i, v in mine.items():
            v.add(0, results[i].observation["rgb"])
        reported: set[int] = set()
        while True:
            running = [i for i, s in enumerate(sim.slots) if not s.done]
            if not running:
                break
            actions = policy.act(running, [results[i].observation for i in running], [results[i].info for i in running])
            full: list = [0] * len(sim.slots)
            for i, a in zip(running, actions):
                if isinstance(a, PolicyFailure):
                    sim.fail(i)
                    failed.append((sim.slots[i].episode.episode_id, a.reason))
                    reported.add(i)
                else:
                    full[i] = a
            if max_failures is not None and len(failed) > max_failures:
                return RolloutResult(predictions=_in_order(finished, episode_ids), views=views, steps=steps,
                                     failed=failed, stopped_early=True)
            results = sim.step(full)
            moved = [i for i in running if sim.slots[i].steps > 0 and sim.slots[i].outcome not in ("stop", "policy_failed")]
            steps += sum(1 for i in running if i not in reported)
            for i in moved:
                if i in mine:
                    mine[i].add(sim.slots[i].steps, results[i].observation["rgb"])
            for i, s in enumerate(sim.slots):
                if s.done and i not in reported:
                    reported.add(i)
                    finished[s.episode.episode_id] = s.prediction()
                    if on_finish:
                        on_finish(finished[s.episode.episode_id])
            if on_step:
                on_step(done + sum(s.done for s in sim.slots), steps)
        done += len(ids)
        views += [mine[i] for i in sorted(mine) if sim.slots[i].outcome != "policy_failed"]
    return RolloutResult(predictions=_in_order(finished, episode_ids), views=views, steps=steps, failed=failed)


def _in_order(finished: dict[str, Prediction], episode_ids: Sequence[str]) -> list[Prediction]:
    return [finished[i] for i in episode_ids if i in finished]


def select_episodes(episodes: Sequence[Episode], *, split: str | None = None, ids: Sequence[str] = (),
                    sample: int | None = None, seed: int = 0) -> list[str]:
    """The ids of the episodes to run, in the order of `episodes` (the run's): those of `split`, those named in
    `ids` (all when empty), then a seeded sample of `sample` of them; a bad request is a ConfigError naming it."""
    if split is not None and split not in SPLITS:
        raise ConfigError(f"{split!r} is not a split (one of {', '.join(SPLITS)})", field="--split")
    by_id = {e.episode_id: e for e in episodes}
    repeated = [i for i, n in Counter(ids).items() if n > 1]
    if repeated:
        raise ConfigError(f"episode {repeated[0]!r} is given twice", field="--episode-id")
    for i in ids:
        if i not in by_id:
            raise ConfigError(f"no episode {i!r} in this run", field="--episode-id")
        if split is not None and by_id[i].split != split:
            raise ConfigError(f"episode {i!r} is in split {by_id[i].split}, not {split}", field="--episode-id")
    named = set(ids)
    picked = [e.episode_id for e in episodes if (split is None or e.split == split) and (not named or e.episode_id
                                                                                         in named)]
    if not picked:
        raise ConfigError(f"no episodes in split {split!r} of this run", field="--split")
    if sample is not None and sample < len(picked):
        keep = np.sort(np.random.default_rng(seed).permutation(len(picked))[:sample])
        picked = [picked[i] for i in keep]
    return picked


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
