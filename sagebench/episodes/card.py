"""The dataset card: README.md (run_layout.DATASET_CARD) at a run's root, so Hugging Face `datasets` (and people) read the run.

Its YAML front matter declares what the Hub indexes a dataset by: `license` (the scenes' licences, read from each
scene.json: the one they share, `other` where they differ, `unknown` where a scene gives none), `task_categories`,
`language`, `size_categories` (by episode rows) and `tags`; and `configs`: `episodes` (the default) with one split
per episode split present (the shards' file pattern), and `validation` with validate's per-trajectory results.
A split with no shard is left out: `datasets` refuses a pattern that matches nothing.
"""

from __future__ import annotations

import json
from pathlib import Path

import pyarrow.parquet as pq

from sagebench.episodes.schema import field_descriptions
from sagebench.episodes.shards import split_pattern
from sagebench.episodes.tasks import REQUIRED, task_field_descriptions
from sagebench.run_layout import EPISODES, PREVIEWS, REPORTS, SCENE_FILE, SCENES, SHARDS, VALIDATION
from sagebench.settings.shared import SPLITS

SIZE_CATEGORIES = ((1_000, "n<1K"), (10_000, "1K<n<10K"), (100_000, "10K<n<100K"), (1_000_000, "100K<n<1M"),
                   (10_000_000, "1M<n<10M"), (100_000_000, "10M<n<100M"), (1_000_000_000, "100M<n<1B"))


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
    licences = scene_licences(run_dir)
    rows = sum(pq.read_metadata(f).num_rows for f in sorted(run_dir.glob(f"{EPISODES}/*/{SHARDS}")))
    # JSON is YAML's flow style: the front matter needs no YAML writer
    front = json.dumps({"pretty_name": title, "license": card_licence(licences), "task_categories": ["robotics"],
                        "language": ["en"], "size_categories": [size_category(rows)], "configs": configs,
                        "tags": ["vision-language-navigation", "robotics"]}, indent=2)
    licence_lines = "\n".join(f"- `{sid}`: {licences.get(sid) or 'not given in its scene.json'}"
                               for sid in sorted(licences)) or "- (no scenes)"
    columns = "\n".join(f"| `{name}` | {doc} |" for name, doc in field_descriptions().items()) + task_columns(run_dir)
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
import pyarrow.parquet as pq, duckdb, pandas as pd, polars as pl
table = pq.read_table("{EPISODES}")                                  # every scene's shards as one table
frame = pd.read_parquet("{EPISODES}")
frame = pl.read_parquet("{EPISODES}")
duckdb.sql("SELECT split, count(*) FROM '{EPISODES}/**/*.parquet' GROUP BY split")
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
- `{VALIDATION}/<scene_id>/`: validate's results, one row per trajectory (the `validation` config).
- `{PREVIEWS}/<scene_id>/paths.png`, `{REPORTS}/<scene_id>/`: sample paths, validate's `report.json` and
  spot-check frames; outside `{EPISODES}/` and `{VALIDATION}/`, which hold Parquet only, so
  `pd.read_parquet("{EPISODES}")` or `pl.read_parquet("{VALIDATION}")` read each as one table.

## Licence

Each scene's, from its `scene.json`:

{licence_lines}
- `manifest.json`: sha256 of every file, the versions and the configuration that made the run.
"""


def task_columns(run_dir: Path) -> str:
    """The task columns' rows of the columns table and the columns each task fills, when a shard has a `task`
    column (a run with tasks other than vln); "" otherwise, so a vln run's card reads as before tasks existed."""
    if not any("task" in pq.read_schema(f).names for f in sorted(run_dir.glob(f"{EPISODES}/*/{SHARDS}"))):
        return ""
    rows = "".join(f"\n| `{name}` | {doc} |" for name, doc in task_field_descriptions().items())
    needs = "\n".join(f"- `{task}`: {', '.join(f'`{n}`' for n in names) or 'the shared columns only'}"
                       for task, names in REQUIRED.items())
    return f"{rows}\n\nWhat each task's rows fill besides the shared columns (docs/tasks.md):\n\n{needs}"


def scene_licences(run_dir: Path) -> dict[str, str | None]:
    """Each scene's `license` from RUN/scenes/<id>/scene.json (None where it gives none or cannot be read)."""
    out: dict[str, str | None] = {}
    for path in sorted(Path(run_dir).glob(f"{SCENES}/*/{SCENE_FILE}")):
        try:
            value = json.loads(path.read_text(encoding="utf-8")).get("license")
        except (OSError, ValueError, AttributeError):
            value = None
        out[path.parent.name] = value if isinstance(value, str) else None
    return out


def card_licence(licences: dict[str, str | None]) -> str:
    """The card's `license`: the scenes' one licence, `unknown` if a scene gives none, `other` if they differ."""
    values = set(licences.values())
    if not values or None in values:
        return "unknown"
    return values.pop() if len(values) == 1 else "other"


def size_category(rows: int) -> str:
    """The Hub's size category of `rows` rows."""
    return next((name for limit, name in SIZE_CATEGORIES if rows < limit), "n>1B")
