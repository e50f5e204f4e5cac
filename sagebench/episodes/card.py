"""The dataset card: README.md (run_layout.DATASET_CARD) at a run's root, so Hugging Face `datasets` (and people) read the run.

Its YAML front matter declares `configs`: `episodes` (the default) with one split per episode split
present (the shards' file pattern), and `validation` with validate's per-trajectory results. A split
with no shard is left out: `datasets` refuses a pattern that matches nothing.
"""

from __future__ import annotations

import json
from pathlib import Path

from sagebench.episodes.schema import field_descriptions
from sagebench.episodes.shards import split_pattern
from sagebench.episodes.splits import SPLITS
from sagebench.run_layout import EPISODES, SHARDS, VALIDATION


def card_text(run_dir: Path, *, title: str = "sagebench run") -> str:
    """The card of the run as it is on disk now (same files, same text)."""
    run_dir = Path(run_dir)
    splits = [s for s in SPLITS if any(run_dir.glob(f"{EPISODES}/*/{split_pattern(s)}"))]
    validation = any(run_dir.glob(f"{VALIDATION}/*/{SHARDS}"))
    configs = [{"config_name": "episodes", "default": True,
                "data_files": [{"split": s, "path": f"{EPISODES}/*/{split_pattern(s)}"} for s in splits]}]
    if validation:
        configs.append({"config_name": "validation",
                        "data_files": [{"split": "trajectories", "path": f"{VALIDATION}/*/{SHARDS}"}]})
    scenes = sorted(p.name for p in (run_dir / EPISODES).glob("*") if p.is_dir())
    # JSON is YAML's flow style: the front matter needs no YAML writer
    front = json.dumps({"pretty_name": title, "configs": configs, "tags": ["vision-language-navigation", "robotics"]},
                       indent=2)
    columns = "\n".join(f"| `{name}` | {doc} |" for name, doc in field_descriptions().items())
    split_lines = "\n".join(f"- `{s}`: `{EPISODES}/*/{split_pattern(s)}`" for s in splits) or "- (none yet)"
    return f"""---
{front}
---

# {title}

Vision-language navigation episodes made by sagebench from {len(scenes)} scene(s): {', '.join(scenes) or 'none'}.
One row per trajectory-instruction pair; positions in metres, world frame Z up, yaw in radians
counter-clockwise from +X.

## Load it

```python
import datasets
episodes = datasets.load_dataset("path/to/this/run")            # config "episodes", one split per split below
results = datasets.load_dataset("path/to/this/run", "validation")["trajectories"]  # validate's results
```

```python
import pyarrow.parquet as pq, duckdb, pandas as pd
table = pq.read_table("{EPISODES}")                                  # every scene's shards as one table
duckdb.sql("SELECT split, count(*) FROM '{EPISODES}/*/{SHARDS}' GROUP BY split")
frame = pd.read_parquet("{EPISODES}")
```

## Splits

{split_lines}

Unseen splits hold whole scenes; seen splits share scenes with train (one split per shard file).

## Episode columns

| column | meaning |
| --- | --- |
{columns}

## Other files

- `scenes/<scene_id>/`: the normalised scene, top-down maps, Gaussians (`gaussians.ply`), the USD stage
  (`scene.usda` + `geometry.usdc`) and the MuJoCo model (`scene.xml`).
- `validation/<scene_id>/`: replay results per trajectory, `report.json`, spot-check frames.
- `manifest.json`: sha256 of every file, the versions and the configuration that made the run.
"""
