"""WebDataset tar shards: one sample per agent step, its files named `<key>.<field>` (key = episode id and step),
written so that equal samples give equal bytes (sorted fields, zero mtimes and owners)."""

from __future__ import annotations

import io
import json
import tarfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

import cv2
import numpy as np

from sagebench.fileio import staged_file

DEPTH_SCALE = 1000  # depth PNGs hold millimetres (uint16; 0 = nothing drawn, 65.535 m the largest)


def sample_key(episode_id: str, step: int) -> str:
    """The sample's key: WebDataset groups files by the name up to the first dot, so the key has none."""
    return f"{episode_id.replace('.', '_')}_{step:05d}"


def depth_png(depth: np.ndarray) -> bytes:
    """[H, W] float32 metres -> 16-bit PNG of millimetres (rounded, clipped to 0..65535)."""
    mm = np.clip(np.rint(np.asarray(depth, np.float64) * DEPTH_SCALE), 0, np.iinfo(np.uint16).max).astype(np.uint16)
    ok, buf = cv2.imencode(".png", mm)
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return buf.tobytes()


def sample_json(meta: dict) -> bytes:
    return (json.dumps(meta, sort_keys=True, ensure_ascii=False, separators=(",", ":")) + "\n").encode("utf-8")


class ShardWriter:
    """Appends samples (key, {field: bytes}) to an open tar file."""

    def __init__(self, fh):
        self._tar = tarfile.open(fileobj=fh, mode="w", format=tarfile.USTAR_FORMAT)
        self.samples = 0

    def add(self, key: str, files: dict[str, bytes]) -> None:
        for field in sorted(files):
            data = files[field]
            info = tarfile.TarInfo(f"{key}.{field}")
            info.size, info.mtime, info.mode = len(data), 0, 0o644
            info.uid = info.gid = 0
            info.uname = info.gname = ""
            self._tar.addfile(info, io.BytesIO(data))
        self.samples += 1

    def close(self) -> None:
        self._tar.close()


@contextmanager
def open_shard(path: Path) -> Iterator[ShardWriter]:
    """A shard written whole or not at all (a temporary sibling renamed into place)."""
    with staged_file(path) as fh:
        writer = ShardWriter(fh)
        yield writer
        writer.close()


def shard_samples(path: Path) -> int:
    """Samples in a finished shard (the number of distinct keys)."""
    with tarfile.open(path) as tar:
        return len({m.name.split(".", 1)[0] for m in tar.getmembers()})


def chunks(items: list, size: int) -> Iterable[list]:
    return (items[i: i + size] for i in range(0, len(items), size))
