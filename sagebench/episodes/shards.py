"""Write episode rows as Parquet shards part-NNNNN.parquet, each complete or absent."""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from sagebench.episodes.schema import EPISODE_SCHEMA
from sagebench.errors import DataError
from sagebench.fileio import write_bytes


def shard_name(index: int) -> str:
    return f"part-{index:05d}.parquet"


def rows_table(rows: Sequence[dict[str, Any]]) -> pa.Table:
    """Rows (dicts keyed by column name) as a table with exactly EPISODE_SCHEMA."""
    return pa.Table.from_pylist(list(rows), schema=EPISODE_SCHEMA)


def table_bytes(table: pa.Table) -> bytes:
    """Parquet bytes; zstd, no pandas metadata, so equal tables give equal bytes."""
    sink = io.BytesIO()
    pq.write_table(table, sink, compression="zstd", store_schema=True)
    return sink.getvalue()


def write_shards(rows: Sequence[dict[str, Any]], out_dir: Path, shard_size: int) -> list[Path]:
    """Write rows in order into out_dir/part-00000.parquet, part-00001.parquet, ... of `shard_size` rows."""
    if shard_size < 1:
        raise ValueError("shard_size must be at least 1")
    paths = []
    for index, lo in enumerate(range(0, max(len(rows), 1), shard_size)):
        path = out_dir / shard_name(index)
        write_bytes(path, table_bytes(rows_table(rows[lo:lo + shard_size])))
        paths.append(path)
    return paths


def read_episodes(path: Path) -> pa.Table:
    """All shards of one episodes/<scene_id>/ directory (or one shard file) as one table."""
    files = sorted(path.glob("part-*.parquet")) if path.is_dir() else [path]
    for f in files:
        check_shard_schema(pq.read_schema(f), f)
    return pa.concat_tables([pq.read_table(f, schema=EPISODE_SCHEMA) for f in files])


OPTIONAL_COLUMNS = frozenset({"split"})  # shards written before the split column lack it


def check_shard_schema(schema: pa.Schema, path: Path) -> None:
    """Every column of EPISODE_SCHEMA (but the optional ones) with its type: a shard of another table is a DataError."""
    for field in EPISODE_SCHEMA:
        if field.name not in schema.names:
            if field.name in OPTIONAL_COLUMNS:
                continue
            raise DataError(f"not an episode shard: column missing (has {', '.join(schema.names[:5])}"
                            f"{', ...' if len(schema.names) > 5 else ''})", path=path, field=field.name)
        got = schema.field(field.name).type
        if got != field.type:
            raise DataError(f"column type {got}, expected {field.type}", path=path, field=field.name)
