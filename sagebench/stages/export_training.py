"""`export-training`: a run's episodes as imitation-learning data, the reference path's discrete actions executed in
the simulator with every step's view (sagebench/training/export.py; layout in docs/training_export.md).

Reads RUN/episodes/<id>/part-*.parquet and RUN/scenes/<id>/ (scene.json, topdown.npz, gaussians.ply, scene.xml,
colliders/). Writes OUT/export.json, OUT/shards/<split>-NNNNNN.tar (WebDataset) and OUT/index.json; never the run.
"""

from __future__ import annotations

import time
from pathlib import Path

from sagebench import ui
from sagebench.episodes.tasks import VLN
from sagebench.settings.export_training import TrainingExportConfig
from sagebench.threads import share_cores
from sagebench.training.export import TrainingExport, export_training


def run_export_training(run_dir: Path, out: Path, config: TrainingExportConfig) -> TrainingExport:
    """Export with a progress bar (episodes, frames/s), the renderer's threads on every core, waiting passively."""
    from sagebench.navsim.world import run_episodes

    share_cores()

    total = len([e for e in run_episodes(run_dir)[0] if config.split in (None, e.split) and e.task == VLN])
    start = time.perf_counter()
    with ui.progress(total, "export-training") as update:
        return export_training(run_dir, out, config, on_progress=lambda episodes, frames: update(
            episodes, f"{frames / max(time.perf_counter() - start, 1e-9):.1f} frames/s"))
