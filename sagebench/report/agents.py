"""The agents a report compares: each predictions file scored by `evaluate` (episodes without a prediction
allowed, and shown as such), named by its file."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

from sagebench.errors import ConfigError
from sagebench.evaluation.scoring import EpisodeScore
from sagebench.settings.evaluate import EvaluateConfig
from sagebench.stages.evaluate import Evaluation, evaluate


@dataclass(frozen=True)
class Agent:
    name: str  # the predictions file's stem (with its folder where two stems are the same)
    evaluation: Evaluation

    def score(self, episode_id: str) -> EpisodeScore | None:
        """The episode's score; None when it was not scored (a rollout that was not asked to run it)."""
        return self._by_id.get(episode_id)

    @cached_property
    def _by_id(self) -> dict[str, EpisodeScore]:
        return {s.episode.episode_id: s for s in self.evaluation.scores}


def score_agents(run_dir: Path, predictions: Sequence[Path], scene_id: str | None = None) -> list[Agent]:
    """Every predictions file scored against the run (or `scene_id`), in the order given; a file given twice is
    a ConfigError."""
    paths = [Path(p) for p in predictions]
    seen = {p.resolve() for p in paths}
    if len(seen) < len(paths):
        raise ConfigError("a predictions file is given twice", field="--predictions")
    names = agent_names(paths)
    config = EvaluateConfig(allow_missing=True)
    return [Agent(name, evaluate(run_dir, p, config, scene_id=scene_id)) for name, p in zip(names, paths)]


def agent_names(paths: Sequence[Path]) -> list[str]:
    """Each file's stem, or folder/stem where stems repeat."""
    stems = [p.stem for p in paths]
    return [s if stems.count(s) == 1 else f"{p.parent.name}/{s}" for s, p in zip(stems, paths)]
