"""`sagebench verify`: re-hash a run against its manifest and its stamps, or regenerate it and compare byte for
byte."""

from __future__ import annotations

import json
import tempfile
from collections.abc import Container, Iterable
from dataclasses import dataclass, replace
from pathlib import Path

from sagebench.errors import DataError, SagebenchError
from sagebench.pipeline.manifest import FileDiff, compare, hash_run, parquet_rows
from sagebench.run_layout import CONTRACT, MANIFEST, SCENE_FILE, SCENES, STAMPS, USD
from sagebench.scene.loader import parse_spec
from sagebench.stamps import read_stamp, stamp_problems, stamped_places
from sagebench.validation.usd_stage import check_stage
from sagebench.versions import likely_cause, output_versions


def read_manifest(run_dir: Path) -> dict:
    manifest = _manifest_if_any(run_dir)
    if manifest is None:
        raise DataError("no manifest.json: this is not the directory of a `sagebench run`", path=run_dir)
    return manifest


def _manifest_if_any(run_dir: Path) -> dict | None:
    path = Path(run_dir) / MANIFEST
    try:
        manifest = json.loads(path.read_text())
    except FileNotFoundError:
        return None
    except (OSError, ValueError, RecursionError) as err:  # ValueError: bad JSON, UTF-8, a 5,000-digit number
        raise DataError(f"unreadable manifest: {str(err).split(';')[0] or type(err).__name__}", path=path) from None
    if not isinstance(manifest, dict) or not isinstance(manifest.get("files"), dict):
        raise DataError("the manifest has no 'files' table", path=path)
    return manifest


def verify_run(run_dir: Path) -> FileDiff:
    """Compare every file of the run's scenes with the manifest's hashes and with the stamps of the stages that
    wrote them, and check their content: every Parquet file holds the rows the manifest records, every scene's
    USD stage opens with a prim per object. A stage the manifest records as failed fails the run too. A run
    made stage by stage (no manifest) is checked against its stamps alone."""
    run_dir = Path(run_dir)
    manifest = _manifest_if_any(run_dir)
    if manifest is None:
        stamped = check_stamps(run_dir, None)
        if not stamped.listed:
            raise DataError(f"no {MANIFEST} and no stamps ({STAMPS}/): nothing records what this run's files "
                            "should be (`sagebench run` and the stage commands write them)", path=run_dir)
        return FileDiff((), (), (), broken=(*stamped.lines(), *content_problems(run_dir, {"files": stamped.listed})),
                        against="the stamps of the stages that wrote them")
    scenes = manifest.get("inputs") if isinstance(manifest.get("inputs"), dict) else None
    diff = compare(manifest["files"], hash_run(run_dir, scenes))
    named = {*diff.changed, *diff.missing, *diff.extra}  # a stamp's word on these would say it twice
    return replace(diff, failed=failed_stages(manifest), broken=(
        *content_problems(run_dir, manifest), *check_stamps(run_dir, scenes).lines(leave_out=named)))


@dataclass(frozen=True)
class StampCheck:
    listed: dict[str, str]  # every file the stamps list: run-relative path -> sha256
    problems: tuple[tuple[str, str], ...]  # (run-relative path, why) for each file that differs from its stamp

    def lines(self, leave_out: Container[str] = ()) -> tuple[str, ...]:
        return tuple(f"{rel}: {why}" for rel, why in self.problems if rel not in leave_out)


def check_stamps(run_dir: Path, scene_ids: Iterable[str] | None) -> StampCheck:
    """Every file the stamps of the scenes (default: every scene with stamps) list, against its stamp."""
    root = run_dir / STAMPS
    ids = sorted(d.name for d in root.glob("*") if d.is_dir()) if scene_ids is None else sorted(scene_ids)
    listed, problems = {}, []
    for sid in ids:
        for stage in CONTRACT:
            listed |= (read_stamp(run_dir, sid, stage) or {"outputs": {}})["outputs"]
        problems += [(path.relative_to(run_dir).as_posix(), why)
                     for path, why in stamp_problems(run_dir, sid, stamped_places(run_dir, sid))]
    return StampCheck(listed, tuple(problems))


def content_problems(run_dir: Path, manifest: dict) -> tuple[str, ...]:
    """"PATH: why" for each listed Parquet file whose rows differ from the manifest's, and each listed scene whose
    scene.usda does not open with its objects."""
    out = []
    rows = manifest.get("rows") if isinstance(manifest.get("rows"), dict) else {}
    for rel, want in sorted(rows.items()):
        if (run_dir / rel).is_file():
            try:
                got = parquet_rows(run_dir / rel)
            except (OSError, ValueError) as err:  # pyarrow's ArrowInvalid is a ValueError
                out.append(f"{rel}: not a readable Parquet file ({_first_line(err)})")
                continue
            if got != want:
                out.append(f"{rel}: {got} rows, the manifest records {want}")
    for rel in sorted(k for k in manifest["files"] if k.endswith(f"/{USD}") and k.startswith(f"{SCENES}/")):
        scene_dir = (run_dir / rel).parent
        try:
            spec_path = scene_dir / SCENE_FILE
            spec = parse_spec(spec_path.read_text(encoding="utf-8"), spec_path)
            check_stage(scene_dir, {o.instance_id: o.category for o in spec.objects})
        except (SagebenchError, OSError) as err:
            out.append(f"{rel}: {_first_line(err)}")
    return tuple(out)


def _first_line(err: BaseException) -> str:
    return (str(err).strip().splitlines() or [type(err).__name__])[0]


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
