"""`export-vlnce`: a run's episodes as a VLN-CE / habitat dataset, in habitat's Y-up frame.

Reads RUN/episodes/<id>/part-*.parquet and RUN/scenes/<id>/scene.json + meshes/. Writes into OUT:
{split}/{split}.json.gz per split (R2R-CE episodes with the vocabulary) and {split}/{split}_gt.json.gz (the oracle's
teacher path: NDTW's locations, the recollect trainer's actions), vocab.txt (one word a line), vlnce_opts.txt (the
VLN-CE config options for this data, `KEY VALUE` a line) and scenes/<id>/<id>.glb (every visual mesh of the scene).
instruction_tokens index the run's vocabulary (every exported instruction's words, split by the tokenizer chosen) or
the one given (a pretrained VLN-CE model's), as rollout's closed loop does (navsim/simulator.py), and the files hold
that vocabulary. Everything is computed before the first byte is written; rows without an instruction
(gen-trajectories --instructions none) and rows of the tasks other than vln (R2R's format holds
instruction-following episodes only; docs/tasks.md) are left out, and counted.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import pyarrow as pa

from sagebench.episodes.load import episode_from_row
from sagebench.episodes.shards import read_episodes
from sagebench.episodes.tasks import VLN, row_task
from sagebench.errors import ConfigError, DataError
from sagebench.fileio import write_bytes, write_text
from sagebench.run_layout import CONTRACT, require, run_episodes_dir, run_scene_dir, run_scenes
from sagebench.scene.loader import load_scene
from sagebench.navsim.teacher import teacher_path
from sagebench.settings.export_vlnce import VlnceExportConfig
from sagebench.settings.shared import SPLITS, MetricConfig
from sagebench.vlnce.episodes import dataset_bytes, scene_glb_path
from sagebench.vlnce.gt import gt_bytes, gt_entry
from sagebench.vlnce.overrides import DATA, GT, opts_text, vlnce_opts
from sagebench.vlnce.glb import scene_glb
from sagebench.vlnce.vocab import Vocabulary, read_vocabulary

VOCAB_FILE = "vocab.txt"
OPTS_FILE = "vlnce_opts.txt"
SCENES_DIR = "scenes"


def split_file(split: str) -> str:
    return DATA.format(split=split)


def gt_file(split: str) -> str:
    return GT.format(split=split)


@dataclass(frozen=True)
class VlnceExport:
    out_dir: Path
    episodes: dict[str, int]  # split -> episodes written
    scenes: list[str]
    vocabulary: int  # words, special tokens included
    skipped: int = 0  # rows without an instruction
    other_tasks: dict[str, int] = field(default_factory=dict)  # task -> its rows, left out (vln only is exported)
    files: list[Path] = field(default_factory=list)
    opts: list[tuple[str, str]] = field(default_factory=list)  # VLN-CE config options, as in OPTS_FILE
    radii: tuple[float, ...] = ()  # the episodes' goal radii, each once
    coverage: str | None = None  # what the vocabulary given lacks of the instructions (Vocabulary.coverage)

    def lines(self) -> list[str]:
        counts = ", ".join(f"{s} {n}" for s, n in self.episodes.items())
        out = [f"export-vlnce: {sum(self.episodes.values())} episodes ({counts}), {len(self.scenes)} scene GLB(s), "
               f"{self.vocabulary} words -> {self.out_dir}"]
        if self.coverage:
            out.append(self.coverage)
        if self.skipped:
            out.append(f"left out {self.skipped} rows without an instruction")
        if self.other_tasks:
            out.append(f"left out {sum(self.other_tasks.values())} episodes of tasks other than vln ("
                       f"{', '.join(f'{t} {n}' for t, n in self.other_tasks.items())}): R2R's format holds VLN "
                       "episodes only")
        if "val_unseen" not in self.episodes:
            out.append("no val_unseen split (its scenes are all seen ones): VLN-CE evaluates on "
                       f"{dict(self.opts)['EVAL.SPLIT']} instead")
        if len(self.radii) > 1:
            out.append(f"goal radii {', '.join(f'{r:g}' for r in self.radii)} m: VLN-CE takes one success distance, "
                       f"the largest")
        out.append(f"VLN-CE config options ({self.out_dir / OPTS_FILE}; run.py ... $(cat {OPTS_FILE})):")
        out += [f"  {k} {v}" for k, v in self.opts]
        return out


def export_vlnce(run_dir: Path, out_dir: Path, *, split: str | None = None,
                 config: VlnceExportConfig = VlnceExportConfig()) -> VlnceExport:
    """Write the dataset of every split of the run (or of `split`) into `out_dir`, its tokens as `config` says."""
    if split is not None and split not in SPLITS:
        raise ConfigError(f"{split!r} is not a split (one of {', '.join(SPLITS)})", field="--split")
    rows, skipped, other = [], 0, {}
    for row in _run_rows(Path(run_dir)):
        if row_task(row) != VLN:
            other[row_task(row)] = other.get(row_task(row), 0) + 1
        elif row["instruction_text"] is None:
            skipped += 1
        else:
            rows.append(row)
    by_split = {s: [r for r in rows if r["split"] == s] for s in SPLITS if split in (None, s)}
    by_split = {s: v for s, v in by_split.items() if v}
    if not by_split:
        what = f"split {split!r}" if split is not None else "any split"
        besides = f" (only {sum(other.values())} episodes of tasks other than vln)" if other else ""
        raise DataError(f"no episodes with an instruction in {what}{besides}", path=Path(run_dir))
    scenes = sorted({r["scene_id"] for v in by_split.values() for r in v})
    vocab, coverage = _vocabulary(config, [r["instruction_text"] for r in rows],
                                  [r["instruction_text"] for v in by_split.values() for r in v])
    files = {split_file(s): dataset_bytes(v, vocab) for s, v in by_split.items()}
    files.update({gt_file(s): _gt(v, Path(run_dir)) for s, v in by_split.items()})
    radii = tuple(sorted({float(r["goal_radius"]) for v in by_split.values() for r in v}))
    opts = vlnce_opts(Path(out_dir), SCENES_DIR, list(by_split), len(vocab.word_list), radii[-1],
                      MetricConfig().ndtw_threshold)
    files[OPTS_FILE] = opts_text(opts).encode()
    for sid in scenes:
        files[f"{SCENES_DIR}/{scene_glb_path(sid)}"] = scene_glb(load_scene(run_scene_dir(run_dir, sid)))
    written = []
    for rel, data in files.items():
        write_bytes(Path(out_dir) / rel, data)
        written.append(Path(out_dir) / rel)
    write_text(Path(out_dir) / VOCAB_FILE, vocab.to_text())
    return VlnceExport(Path(out_dir), {s: len(v) for s, v in by_split.items()}, scenes, len(vocab.word_list),
                       skipped, dict(sorted(other.items())), [*written, Path(out_dir) / VOCAB_FILE], opts, radii,
                       coverage)


def _vocabulary(config: VlnceExportConfig, every: list[str], exported: list[str]) -> tuple[Vocabulary, str | None]:
    """(the vocabulary instruction_tokens index, what it lacks of the `exported` instructions when it was given):
    the one given (--vocab), else the words of `every` split's instructions (one vocabulary for all) split by the
    tokenizer chosen."""
    if config.vocab is None:
        return Vocabulary.from_texts(every, config.tokenizer), None
    vocab = read_vocabulary(config.vocab, config.tokenizer)
    return vocab, vocab.coverage(config.vocab, exported)


def _run_rows(run_dir: Path) -> list[dict]:
    """Every episode row of the run, scene by scene."""
    rows = []
    for sid in run_scenes(run_dir, having="episodes"):
        require(CONTRACT["export_vlnce"].reads, run_dir, sid)
        try:
            rows += read_episodes(run_episodes_dir(run_dir, sid)).to_pylist()
        except (OSError, pa.ArrowException) as err:
            raise DataError(f"cannot read episode shards: {err}", path=run_episodes_dir(run_dir, sid)) from None
    return rows


def _gt(rows: list[dict], run_dir: Path) -> bytes:
    """The {split}_gt.json.gz of one split's rows: the oracle's teacher path of each episode."""
    entries = {}
    for row in rows:
        path = teacher_path(episode_from_row(row, run_episodes_dir(run_dir, row["scene_id"])))
        entries[row["episode_id"]] = gt_entry(path.actions, path.positions)
    return gt_bytes(entries)
