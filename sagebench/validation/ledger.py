"""A run's files against its manifest.json: every file the manifest lists for a scene exists, hashes to its
recorded sha256 and, for Parquet, holds the recorded rows. validate checks what it reads this way before it
replays anything, so a deleted or byte-flipped shard fails instead of passing on what is left.

The manifest is `sagebench run`'s (pipeline/manifest.py); a run made stage by stage has none, and validate checks
its stamps instead (sagebench.stamps).
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path

from sagebench.errors import DataError
from sagebench.fileio import sha256_file
from sagebench.run_layout import MANIFEST


def read_ledger(run_dir: Path) -> dict | None:
    """The run's manifest as data, None when there is none (a DataError when it is unreadable)."""
    path = Path(run_dir) / MANIFEST
    if not path.exists():
        return None
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError) as err:
        raise DataError(f"unreadable manifest: {str(err).split(';')[0]}", path=path) from None
    if not isinstance(doc, dict) or not isinstance(doc.get("files"), dict):
        raise DataError("the manifest has no 'files' table", path=path)
    return doc


def check_listed(run_dir: Path, prefixes: Iterable[str]) -> int:
    """Check every file the manifest lists under `prefixes` (run-relative, such as "episodes/<id>/"); returns how
    many were checked. A DataError names the first missing, changed or miscounted file."""
    ledger = read_ledger(run_dir)
    if ledger is None:
        return 0
    prefixes = tuple(prefixes)
    rows = ledger.get("rows") if isinstance(ledger.get("rows"), dict) else {}
    listed = {rel: digest for rel, digest in ledger["files"].items() if rel.startswith(prefixes)}
    for prefix in {p for p in prefixes if any(rel.startswith(p) for rel in listed)}:
        for path in sorted((Path(run_dir) / prefix).rglob("*")):
            rel = path.relative_to(run_dir).as_posix()
            if path.is_file() and rel not in listed and not any(part.startswith(".") for part in Path(rel).parts):
                raise DataError(f"not listed in {MANIFEST}: a file the run did not write (`sagebench run` removes "
                                "what is stale)", path=path)
    checked = 0
    for rel, digest in sorted(listed.items()):
        path = Path(run_dir) / rel
        if not path.is_file():
            raise DataError(f"listed in {MANIFEST} but missing: the run is damaged (`sagebench verify` names every "
                            "file that differs, `sagebench run` makes them again)", path=path)
        if sha256_file(path) != digest:
            raise DataError(f"differs from the sha256 {MANIFEST} records: the file was changed or damaged since the "
                            "run (`sagebench run` makes it again)", path=path)
        if rel in rows:
            import pyarrow.parquet as pq

            got = pq.ParquetFile(path).metadata.num_rows
            if got != rows[rel]:
                raise DataError(f"holds {got} rows, {MANIFEST} records {rows[rel]}", path=path)
        checked += 1
    return checked
