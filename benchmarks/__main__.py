"""Run every benchmarks/bench_*.py (each exposes run() -> list of row dicts) and print one table per file.

`python -m benchmarks [NAME ...]` runs only the named benches (e.g. `astar render`).
"""

from __future__ import annotations

import importlib
import sys
import time
from pathlib import Path


def _table(rows: list[dict]) -> str:
    cols: list[str] = []
    for row in rows:
        cols += [c for c in row if c not in cols]
    cells = [[_fmt(row.get(c, "")) for c in cols] for row in rows]
    widths = [max(len(c), *(len(r[i]) for r in cells)) for i, c in enumerate(cols)]
    line = lambda vals: "| " + " | ".join(v.ljust(w) for v, w in zip(vals, widths)) + " |"  # noqa: E731
    return "\n".join([line(cols), "|" + "|".join("-" * (w + 2) for w in widths) + "|", *map(line, cells)])


def _fmt(v: object) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def main(names: list[str]) -> int:
    here = Path(__file__).parent
    benches = sorted(p.stem for p in here.glob("bench_*.py"))
    if names:
        benches = [b for b in benches if b.removeprefix("bench_") in names or b in names]
    if not benches:
        print("no benchmarks yet")
        return 0
    for name in benches:
        start = time.perf_counter()
        rows = importlib.import_module(f"benchmarks.{name}").run()
        print(f"\n## {name.removeprefix('bench_')}  ({time.perf_counter() - start:.0f} s)\n")
        print(_table(rows) if rows else "(no rows)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
