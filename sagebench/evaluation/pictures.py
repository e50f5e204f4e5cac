"""`evaluate --visualize DIR`: one picture per scored episode (episodes/picture.py) with its metrics, named as
SAGE-Bench's evaluator names its own (trajectory_visualization_<scene>_<episode>.png), and DIR/PICTURES_INDEX:
which predictions were drawn and each episode's file. The index marks DIR as an earlier --visualize output (the
folder may be written again) and is written first; the pictures an earlier index lists that this one does not
are removed, so DIR always shows one evaluation."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from sagebench.episodes.picture import AgentPath, episode_picture, scale_for
from sagebench.episodes.preview import plain_map
from sagebench.evaluation.scoring import EpisodeScore
from sagebench.fileio import listed_files, remove_unlisted, write_bytes, write_json
from sagebench.topdown.grid_file import TopdownGrids

PICTURES_INDEX = "pictures.json"
PREFIX = "trajectory_visualization_"
MAX_SIZE_PX = 720  # the map's longer side, at most


def picture_name(scene_id: str, episode_id: str) -> str:
    return f"{PREFIX}{scene_id}_{episode_id}.png"


def title(score: EpisodeScore) -> str:
    e = score.episode
    return f"{e.scene_id}  episode {e.episode_id}  {e.split}  {e.level} / {e.type}"


def notes(score: EpisodeScore) -> list[str]:
    """The metrics under the caption, two lines (one for an episode without a prediction)."""
    if score.prediction is None:
        return ["no prediction: scored as a failure, every metric at its worst"]
    m, c = score.metrics, score.intensity
    contact = "" if c is None else f", {int(np.count_nonzero(c > 0))} with contact"
    return [f"SR {m.sr:g}  OSR {m.osr:g}  SPL {m.spl:.3f}  NE {m.ne:.2f} m  (straight {m.ne_straight:.2f} m)  "
            f"nDTW {m.ndtw:.3f}  SDTW {m.sdtw:.3f}",
            f"CSR {m.csr:.3f}  ICP {m.icp:.3f}  PS {m.ps:.3f}  length {m.path_length:.2f} m  "
            f"{len(score.prediction.poses)} poses{contact} (c(t) {score.icp_source})  "
            + ("stopped" if score.prediction.stopped else "did not stop")]


def draw(score: EpisodeScore, grid: TopdownGrids, base: np.ndarray | None = None) -> bytes:
    """PNG bytes of one scored episode."""
    p = score.prediction
    agent = None if p is None else AgentPath(np.asarray(p.poses, dtype=np.float64), score.intensity)
    e = score.episode
    return episode_picture(grid, e, agent, title(score), e.instruction or "(no instruction)", notes(score),
                           max_size_px=MAX_SIZE_PX, base=base)


def write_pictures(scores: Sequence[EpisodeScore], grids: Mapping[str, TopdownGrids], out_dir: Path,
                   predictions: dict) -> list[Path]:
    """Every score's picture into `out_dir` and the index (module docstring); the pictures' paths."""
    out_dir = Path(out_dir)
    names = {s.episode.episode_id: picture_name(s.episode.scene_id, s.episode.episode_id) for s in scores}
    earlier = listed_files(out_dir / PICTURES_INDEX, "pictures")
    write_json(out_dir / PICTURES_INDEX, {"predictions": predictions, "pictures": names})
    bases = {sid: plain_map(g.navigable, g.occupancy, scale_for(g.navigable.shape, MAX_SIZE_PX))
             for sid, g in grids.items()}
    for s in scores:
        sid = s.episode.scene_id
        write_bytes(out_dir / names[s.episode.episode_id], draw(s, grids[sid], bases[sid]))
    remove_unlisted(out_dir, earlier, names.values())
    return [out_dir / n for n in names.values()]

