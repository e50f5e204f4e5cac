"""Code as it was at an earlier commit, read from git history: the "before" a bench measures today against."""

from __future__ import annotations

import subprocess
import types
from pathlib import Path


def module_at(commit: str, path: str) -> types.ModuleType:
    """The module at `path` (relative to the repository root) as of `commit`, executed afresh under the name
    `<commit>:<path>`. Its numba kernels compile uncached: it has no source file to key a cache on. Raises OSError
    or CalledProcessError where git or that commit is missing."""
    src = subprocess.run(["git", "show", f"{commit}:{path}"], capture_output=True, text=True, check=True,
                         cwd=Path(__file__).parent).stdout
    module = types.ModuleType(f"{Path(path).stem}_at_{commit}")
    exec(compile(src.replace("cache=True", "cache=False"), f"{commit}:{path}", "exec"), module.__dict__)
    return module
