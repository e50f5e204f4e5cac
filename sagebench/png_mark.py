"""The mark on the PNG files sagebench writes outside a run (render's view, a rollout's contact sheet): a tEXt
chunk `Software: sagebench` right after the header, so that a later command recognises the file as its own
and may replace it without --force (run_folder.claim_output_file), while a user's PNG there is never replaced.
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

from sagebench.input_files import read_regular

_TEXT = b"Software\x00sagebench"
MARK = struct.pack(">I", len(_TEXT)) + b"tEXt" + _TEXT + struct.pack(">I", zlib.crc32(b"tEXt" + _TEXT))
_AFTER_HEADER = 8 + 4 + 4 + 13 + 4  # the signature and the IHDR chunk, which every PNG begins with


def marked(png: bytes) -> bytes:
    """`png` (a whole PNG file) with the mark inserted after its header chunk."""
    return png[:_AFTER_HEADER] + MARK + png[_AFTER_HEADER:]


def is_marked(path: Path) -> bool:
    """Whether `path` is a regular file holding a PNG that sagebench marked."""
    head = read_regular(path, limit=None, size=_AFTER_HEADER + len(MARK))
    return head is not None and head.startswith(b"\x89PNG\r\n\x1a\n") and head[_AFTER_HEADER:] == MARK
