"""A scene source as build-scene and run take it: a sagebench scene directory or an InteriorGS folder.

Kept apart from the importer so that telling the two apart (and refusing a bad scene directory) imports none
of the heavy libraries the import needs (tests/test_startup.py).
"""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import Iterator
from pathlib import Path

from sagebench.importers.interiorgs_files import is_interiorgs_folder
from sagebench.settings.build_scene import BuildSceneConfig


@contextlib.contextmanager
def opened_scene(scene_dir: Path, build: BuildSceneConfig = BuildSceneConfig()) -> Iterator[Path]:
    """`scene_dir` itself for a sagebench scene; for an InteriorGS folder, a temporary directory holding its import
    (removed on leaving), so build-scene and run take either."""
    if not is_interiorgs_folder(scene_dir):
        yield Path(scene_dir)
        return
    from sagebench.importers.interiorgs import import_interiorgs, write_imported

    imported = import_interiorgs(Path(scene_dir), build=build)
    with tempfile.TemporaryDirectory(prefix="sagebench-interiorgs-") as tmp:
        out = Path(tmp) / imported.spec.scene_id
        write_imported(imported, out)
        yield out
