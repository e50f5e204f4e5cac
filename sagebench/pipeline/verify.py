"""`sagebench verify`: re-hash a run against its manifest, or regenerate it and compare byte for byte."""

from __future__ import annotations

import json
import tempfile
from dataclasses import replace
from pathlib import Path

from sagebench.errors import DataError
from sagebench.pipeline.manifest import FileDiff, compare, hash_run
from sagebench.run_layout import MANIFEST
from sagebench.versions import likely_cause, output_versions


def read_manifest(run_dir: Path) -> dict:
    path = Path(run_dir) / MANIFEST
    try:
        manifest = json.loads(path.read_text())
    except FileNotFoundError:
        raise DataError("no manifest.json: this is not the directory of a `sagebench run`", path=run_dir) from None
    except (OSError, json.JSONDecodeError) as err:
        raise DataError(f"unreadable manifest: {err}", path=path) from None
    if not isinstance(manifest, dict) or not isinstance(manifest.get("files"), dict):
        raise DataError("the manifest has no 'files' table", path=path)
    return manifest


def verify_run(run_dir: Path) -> FileDiff:
    """Compare every file of the run's scenes with the manifest's hashes; a stage the manifest records as
    failed fails the run too."""
    manifest = read_manifest(run_dir)
    scenes = manifest.get("inputs") if isinstance(manifest.get("inputs"), dict) else None
    diff = compare(manifest["files"], hash_run(Path(run_dir), scenes))
    return replace(diff, failed=failed_stages(manifest))


def failed_stages(manifest: dict) -> tuple[str, ...]:
    """"SCENE at STAGE: why" for every scene the manifest records as failed."""
    failed = manifest.get("failed") if isinstance(manifest.get("failed"), dict) else {}
    return tuple(f"{sid} at {f.get('stage')}: {f.get('message')}" if isinstance(f, dict) else f"{sid}: {f}"
                 for sid, f in sorted(failed.items()))


def regenerate_and_compare(run_dir: Path, config_path: Path, *, workers: int = 1) -> FileDiff:
    """Run CONFIG again into a temporary directory and compare its files with RUN_DIR's manifest; when they
    differ, the diff also names the libraries whose versions differ from the manifest's."""
    from sagebench.pipeline.config import load_run_config
    from sagebench.pipeline.run import run_pipeline

    expected = read_manifest(run_dir)
    with tempfile.TemporaryDirectory(prefix="sagebench-regen-") as tmp:
        config = load_run_config(config_path, out=tmp, workers=workers, executor="local")
        if config.outputs_config() != expected.get("config"):
            raise DataError("this config differs from the one the run was made with (see the manifest's 'config')",
                            path=config_path)
        run_pipeline(config, config_path)
        diff = replace(compare(expected["files"], hash_run(Path(tmp))), failed=failed_stages(expected))
    if diff.ok or not (diff.changed or diff.missing or diff.extra):
        return diff
    return replace(diff, cause=likely_cause(expected.get("versions"), output_versions()))
