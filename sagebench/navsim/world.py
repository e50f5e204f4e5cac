"""One scene of a run, opened for closed-loop episodes: the replay's MuJoCo model, the packed Gaussians and their
renderer, the navigable map (distances on foot, the map's extent) and the episodes with their instructions."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sagebench.episodes.load import load_episodes
from sagebench.episodes.shards import read_episodes
from sagebench.episodes.episode import Episode
from sagebench.metrics.on_foot import NavigableMap
from sagebench.render.backends import Renderer, open_renderer
from sagebench.render.chunks import PackedGaussians, pack
from sagebench.replay.physics import ReplayModel
from sagebench.replay.scene_model import open_replay_model
from sagebench.run_layout import GAUSSIANS, TOPDOWN, run_episodes_dir, run_scene_dir, run_scenes
from sagebench.settings.shared import ReplayConfig
from sagebench.topdown.grid_file import read_topdown_grids
from sagebench.vlnce.vocab import Vocabulary


@dataclass(frozen=True)
class World:
    scene_id: str
    model: ReplayModel
    navmap: NavigableMap
    gaussians: PackedGaussians | None  # None when no image is rendered
    renderer: Renderer | None  # draws the Gaussians (None when no image is rendered)
    bounds: tuple[float, float, float, float]  # x0, y0, x1, y1 of the map: leaving it ends an episode, m

    def inside(self, xy: np.ndarray) -> np.ndarray:
        """[B] bool: points [B, >=2] within the map's extent."""
        xy = np.atleast_2d(xy)
        x0, y0, x1, y1 = self.bounds
        return (xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)


def open_world(run_dir: Path, scene_id: str, *, replay: ReplayConfig, images: Sequence[str] = (),
               renderer: str = "cpu") -> World:
    """Load one scene of a run (Gaussians and a renderer by `renderer`, auto, cpu or gsplat, only when `images`
    names some); the agent's body is the one its map was built for."""
    from sagebench.splats.ply import read_ply

    scene_dir = run_scene_dir(run_dir, scene_id)
    model = open_replay_model(run_dir, scene_id, replay=replay)
    grids = read_topdown_grids(scene_dir / TOPDOWN)
    navmap = NavigableMap(grids.navigable, grids.resolution, grids.origin, snap_radius=model.agent.radius)
    gaussians = pack(read_ply(scene_dir / GAUSSIANS)) if images else None
    drawn = open_renderer(gaussians, renderer, needs=images) if gaussians is not None else None
    return World(scene_id=scene_id, model=model, navmap=navmap, gaussians=gaussians, renderer=drawn, bounds=navmap.bounds)


def run_vocabulary(run_dir: Path, tokenizer: str = "sagebench") -> Vocabulary:
    """The vocabulary of every instruction of the run, every scene's: the one export-vlnce writes (with its
    tokenizer), so tokens in the closed loop are the word ids of the exported dataset."""
    texts = []
    for sid in run_scenes(run_dir, having="episodes"):
        table = read_episodes(run_episodes_dir(run_dir, sid)).select(["instruction_text"])
        texts += [t for t in table.column("instruction_text").to_pylist() if t is not None]
    return Vocabulary.from_texts(texts, tokenizer)


def run_episodes(run_dir: Path, scene_id: str | None = None) -> tuple[list[Episode], dict[str, str]]:
    """The run's episodes (scene then file order) and each one's instruction text ("" without one)."""
    episodes = load_episodes(run_dir, scene_id)
    text: dict[str, str] = {}
    for sid in dict.fromkeys(e.scene_id for e in episodes):
        table = read_episodes(run_episodes_dir(run_dir, sid)).select(["episode_id", "instruction_text"])
        text.update((r["episode_id"], r["instruction_text"] or "") for r in table.to_pylist())
    return episodes, text
