"""A rollout's predictions file while it runs: every finished episode is appended as one whole line the moment it
ends, so a rollout that is killed or stops on policy failures keeps everything it finished.

Each line goes to the file in one write and is flushed to disk (fsync) before the next episode's, so the file is
always whole lines plus at most one torn last line (a kill inside the write). A resumed rollout keeps the whole
lines, drops a torn one, and appends the episodes still to run. When every episode has its line the file is
rewritten in run order (a new file renamed over it), so a resumed rollout ends with the very bytes an
uninterrupted one writes, whatever the order the episodes finished in.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

from sagebench.errors import DataError
from sagebench.evaluation.predictions import Prediction, dumps_prediction, parse_line
from sagebench.fileio import write_text


class Journal:
    """The predictions file of one rollout (module docstring); `lines` maps episode id -> its line."""

    def __init__(self, path: Path, lines: dict[str, str]):
        self.path, self.lines = Path(path), lines
        write_text(self.path, "".join(lines.values()))  # whole lines only, atomically
        self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)

    @classmethod
    def resume(cls, path: Path, asked: Sequence[str]) -> Journal:
        """The journal of an earlier rollout of `asked` at `path`, whole lines kept (none when it is missing)."""
        path, wanted = Path(path), set(asked)
        try:
            text = path.read_text(encoding="utf-8")
        except FileNotFoundError:
            text = ""
        except (OSError, UnicodeDecodeError) as err:
            raise DataError(f"cannot read: {err}", path=path) from None
        lines: dict[str, str] = {}
        whole = text[: text.rfind("\n") + 1]  # a torn last line (no newline) was cut by a kill: run it again
        for n, line in enumerate(whole.splitlines(keepends=True), start=1):
            p = parse_line(line, path, n)
            if p.episode_id not in wanted:
                raise DataError(f"episode {p.episode_id!r} is not one this rollout was asked to run",
                                path=f"{path}:{n}", field="episode_id")
            if p.episode_id in lines:
                raise DataError(f"duplicate episode id {p.episode_id!r}", path=f"{path}:{n}", field="episode_id")
            lines[p.episode_id] = line
        return cls(path, lines)

    def append(self, prediction: Prediction) -> None:
        """Add one finished episode's line, on disk before this returns."""
        data = (dumps_prediction(prediction) + "\n").encode("utf-8")
        view = memoryview(data)
        while view:
            view = view[os.write(self._fd, view):]
        os.fsync(self._fd)
        self.lines[prediction.episode_id] = data.decode("utf-8")

    def finish(self, order: Sequence[str]) -> None:
        """Rewrite the file with its lines in `order` (every id of it must have one) and close it."""
        self.close()
        write_text(self.path, "".join(self.lines[i] for i in order))

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1
