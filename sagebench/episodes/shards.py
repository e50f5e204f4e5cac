"""Write episode rows as Parquet shards part-<split>-NNNNN.parquet, each complete or absent, sized by bytes.

One split per shard, so a split is a file pattern (what a Hugging Face dataset card's `configs` names):
each split's rows, in their order, go into as few shards as keep each under the byte budget, with row
groups of about ROW_GROUP_BYTES.
"""

from __future__ import annotations

import io
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from sagebench.episodes.schema import EPISODE_SCHEMA
from sagebench.episodes.tasks import TASK_SCHEMA, check_task_table, task_field_descriptions
from sagebench.errors import DataError
from sagebench.fileio import write_bytes
from sagebench.settings.shared import SPLITS

ROW_GROUP_BYTES = 16 * 2**20  # compressed; readers (HF's viewer, DuckDB) fetch a row group at a time


def shard_name(split: str, index: int) -> str:
    return f"part-{split}-{index:05d}.parquet"


def split_pattern(split: str) -> str:
    """The glob of one split's shards in an episodes/<scene_id>/ directory."""
    return f"part-{split}-*.parquet"


def rows_table(rows: Sequence[dict[str, Any]], schema: pa.Schema = EPISODE_SCHEMA) -> pa.Table:
    """Rows (dicts keyed by column name) as a table with exactly `schema` (EPISODE_SCHEMA, or TASK_SCHEMA when a
    task other than vln is written: episodes/tasks.py)."""
    return pa.Table.from_pylist(list(rows), schema=schema)


def table_bytes(table: pa.Table, row_group_rows: int | None = None) -> bytes:
    """Parquet bytes; zstd, no pandas metadata, so equal tables give equal bytes."""
    sink = io.BytesIO()
    pq.write_table(table, sink, compression="zstd", store_schema=True, row_group_size=row_group_rows)
    return sink.getvalue()


def shard_tables(table: pa.Table, shard_bytes: int) -> list[bytes]:
    """`table` as Parquet files of at most about `shard_bytes` each (at least one row each, one file when
    empty), the rows split evenly in order; row groups of about ROW_GROUP_BYTES."""
    if shard_bytes < 1:
        raise ValueError("shard_bytes must be at least 1")
    whole = table_bytes(table)
    if table.num_rows == 0:
        return [whole]
    per_row = len(whole) / table.num_rows  # the compressed size of a row, on average
    count = min(table.num_rows, max(1, math.ceil(len(whole) / shard_bytes)))
    rows = math.ceil(table.num_rows / count)
    group = max(1, math.floor(ROW_GROUP_BYTES / per_row))
    return [table_bytes(table.slice(lo, rows), group) for lo in range(0, table.num_rows, rows)]


def write_shards(rows: Sequence[dict[str, Any]], out_dir: Path, shard_bytes: int,
                 schema: pa.Schema = EPISODE_SCHEMA) -> list[Path]:
    """Write each split's rows (in order, as `schema`) into out_dir/part-<split>-00000.parquet, ... of about
    `shard_bytes`; splits in sorted order. No rows: one empty part-empty-00000.parquet keeps the schema. A split that is not one
    of SPLITS is a DataError before anything is written."""
    splits = sorted({r["split"] for r in rows}) or ["empty"]
    bad = next((s for s in splits if s not in (*SPLITS, "empty")), None)
    if bad is not None:  # a name from an input must never leave out_dir: the split is part of every file name
        raise DataError(f"split {bad!r} is not one of {', '.join(SPLITS)}; no shard was written", path=out_dir,
                        field="split")
    paths = []
    for split in splits:
        table = rows_table([r for r in rows if r["split"] == split], schema)
        for index, data in enumerate(shard_tables(table, shard_bytes)):
            path = out_dir / shard_name(split, index)
            write_bytes(path, data)
            paths.append(path)
    return paths


def read_episodes(path: Path) -> pa.Table:
    """All shards of one episodes/<scene_id>/ directory (or one shard file) as one table: EPISODE_SCHEMA when no
    shard has a `task` column, else TASK_SCHEMA (a shard without one holds vln rows: its task columns read null)."""
    files = sorted(path.glob("part-*.parquet")) if path.is_dir() else [path]
    schemas = [pq.read_schema(f) for f in files]
    for f, schema in zip(files, schemas, strict=True):
        check_shard_schema(schema, f)
    schema = TASK_SCHEMA if any("task" in s.names for s in schemas) else EPISODE_SCHEMA
    tables = [read_shard(f, schema) for f in files]
    for f, table in zip(files, tables, strict=True):
        check_task_table(table, f)
    return pa.concat_tables(tables)


def read_shard(path: Path, schema: pa.Schema) -> pa.Table:
    """One shard file as a table of `schema` (a column it lacks reads null). Read as one file, not as a dataset:
    pyarrow.dataset imports pandas, which alone costs a command more CPU than the reading."""
    table = pq.ParquetFile(path).read()
    columns = [table.column(f.name).cast(f.type) if f.name in table.column_names else pa.nulls(len(table), f.type)
               for f in schema]
    return pa.Table.from_arrays(columns, schema=schema)


OPTIONAL_COLUMNS = frozenset({"split"})  # shards written before the split column lack it
TASK_COLUMNS = frozenset(task_field_descriptions())  # a vln-only shard has none of them


def check_shard_schema(schema: pa.Schema, path: Path) -> None:
    """Every column of EPISODE_SCHEMA (but the optional ones) with its type, and the task columns with theirs when
    the shard has a `task` column: a shard of another table is a DataError."""
    tasks = "task" in schema.names
    for field in TASK_SCHEMA:
        if field.name not in schema.names:
            if field.name in OPTIONAL_COLUMNS or (field.name in TASK_COLUMNS and not tasks):
                continue
            raise DataError(f"not an episode shard: column missing (has {', '.join(schema.names[:5])}"
                            f"{', ...' if len(schema.names) > 5 else ''})", path=path, field=field.name)
        got = schema.field(field.name).type
        if got != field.type:
            raise DataError(f"column type {got}, expected {field.type}", path=path, field=field.name)
