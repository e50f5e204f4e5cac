"""The stamp a stage leaves for a scene, RUN/.stamps/<scene_id>/<stage>.json: the key of what it read, the sha256
of every file it wrote, its summary line and the agent's body it worked for.

`sagebench run` and the stage commands (build-scene, gen-trajectories, export-usd, validate,
import-sage-episodes) write the same stamp. `run` skips a stage whose stamp is current; a stage command checks
the files it reads against the stamps of the stages that wrote them (run_layout.CONTRACT says which), and
validate and verify check every file a stamp lists: present, the same sha256, and no file in a directory a
stage wrote whole that its stamp does not list. A stage with no stamp (a run of an older sagebench) is not
checked.

The key is a hash of the sagebench version, the versions of Python and the libraries that shape outputs
(sagebench.versions), the stage's settings and every input file's path and content hash.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from sagebench import __version__
from sagebench.errors import DataError
from sagebench.fileio import dumps_json, sha256_file, write_text
from sagebench.run_layout import (
    CONTRACT, SCENE_FILE, SEMANTIC_MAP, STAGE_COMMANDS, STAMPS, Place, files, mesh_names, root_dir, run_scene_dir,
    stage_files,
)
from sagebench.topdown.semantic_map import read_semantic_map
from sagebench.versions import output_versions


def stamp_path(run_dir: Path, scene_id: str, stage: str) -> Path:
    return Path(run_dir) / STAMPS / scene_id / f"{stage}.json"


def read_stamp(run_dir: Path, scene_id: str, stage: str) -> dict[str, Any] | None:
    """The stamp as data; None when there is none, or it is unreadable or not a stamp (the stage counts as
    unstamped: `run` runs it again and writes a new one)."""
    try:
        stamp = json.loads(stamp_path(run_dir, scene_id, stage).read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    return stamp if isinstance(stamp, dict) and isinstance(stamp.get("outputs"), dict) else None


def stage_key(stage: str, settings: dict[str, Any], inputs: Iterable[Path], run_dir: Path,
              source: Path | None = None) -> str:
    """sha256 of (versions, stage, settings, every input file's path, relative to `source` when it lies there,
    else to the run, and content hash)."""
    h = hashlib.sha256(f"{__version__}\0{stage}\0".encode())
    h.update(json.dumps(output_versions(), sort_keys=True).encode() + b"\0")
    h.update(json.dumps(settings, sort_keys=True).encode())
    for p in inputs:
        root = source if source is not None and p.is_relative_to(source) else run_dir
        h.update(b"\0" + p.relative_to(root).as_posix().encode() + b"\0" + sha256_file(p).encode())
    return h.hexdigest()


def output_hashes(stage: str, run_dir: Path, scene_id: str) -> dict[str, str]:
    """{run-relative path: sha256} of every file the stage's places hold now."""
    return {p.relative_to(run_dir).as_posix(): sha256_file(p) for p in stage_files(stage, "writes", run_dir, scene_id)}


def write_stamp(run_dir: Path, scene_id: str, stage: str, key: str, message: str, ok: bool) -> None:
    """Stamp what the stage just wrote; call it after its outputs are in place. The stamps of other stages that
    write the same places (import-sage-episodes and gen-trajectories both write episodes/) go: those files are
    no longer theirs."""
    for other in CONTRACT:
        if other != stage and set(CONTRACT[other].writes) & set(CONTRACT[stage].writes):
            stamp_path(run_dir, scene_id, other).unlink(missing_ok=True)
    write_text(stamp_path(run_dir, scene_id, stage), dumps_json({
        "key": key, "outputs": output_hashes(stage, run_dir, scene_id), "message": message, "ok": ok,
        "agent": _agent(run_dir, scene_id)}))


def _agent(run_dir: Path, scene_id: str) -> dict[str, float] | None:
    """The agent's body the stage worked for: the one the scene's map records (build-scene wrote it from its
    settings; every later stage takes it from there). None when the scene has no map."""
    path = run_scene_dir(run_dir, scene_id) / SEMANTIC_MAP
    return read_semantic_map(path).agent().model_dump(mode="json") if path.is_file() else None


def stamp_problems(run_dir: Path, scene_id: str, places: Iterable[Place]) -> Iterator[tuple[Path, str]]:
    """(file, why) for each file of `places` (run places, not the source scene) that differs from the stamp of
    the stage that wrote it: changed, missing, or not listed. A place whose writer has no stamp is not checked."""
    stamps = {s: read_stamp(run_dir, scene_id, s) for s in CONTRACT}
    for place in dict.fromkeys(p for p in places if p.root != "source"):
        stage = next((s for s in CONTRACT if place in CONTRACT[s].writes and stamps[s] is not None), None)
        if stage is None:
            continue
        outputs = stamps[stage]["outputs"]
        for rel in sorted(_names(place, run_dir, scene_id, outputs)):
            path = Path(run_dir) / rel
            why = _differs(path, outputs.get(rel))
            if why is not None:
                stamp = stamp_path(run_dir, scene_id, stage).relative_to(run_dir).as_posix()
                yield path, WHY[why].format(command=STAGE_COMMANDS[stage], stamp=stamp)


def _names(place: Place, run_dir: Path, scene_id: str, outputs: dict[str, str]) -> set[str]:
    """Run-relative paths of `place`: the files it holds now and those the stamp lists in it."""
    now = {p.relative_to(run_dir).as_posix() for p in files(place, run_dir, scene_id)}
    root = root_dir(place.root, run_dir, scene_id)
    if place.meshes:
        return now | {(root / m).relative_to(run_dir).as_posix() for m in mesh_names(root / SCENE_FILE)}
    top = (root / place.rel).relative_to(run_dir).as_posix()
    return now | {rel for rel in outputs if rel == top or rel.startswith(f"{top}/")}


WHY = {
    "stray": "not written by {command}: its stamp {stamp} does not list it; remove it, or run {command} again",
    "missing": "missing: {command} wrote it (its stamp {stamp} lists it); run {command} again",
    "changed": "changed since {command} wrote it (its stamp {stamp} records another sha256); run {command} again",
}


def _differs(path: Path, recorded: str | None) -> str | None:
    """How `path` differs from the file its stamp records (a key of WHY), None when it does not."""
    if recorded is None:
        return "stray" if path.is_file() else None
    if not path.is_file():
        return "missing"
    return "changed" if sha256_file(path) != recorded else None


def check_stamped(run_dir: Path, scene_id: str, places: Iterable[Place]) -> None:
    """A DataError naming the first file of `places` that differs from its writer's stamp, and why."""
    for path, why in stamp_problems(run_dir, scene_id, places):
        raise DataError(why, path=path)


def check_reads(stage: str, run_dir: Path, scene_id: str) -> None:
    """The files `stage` reads for the scene, checked against the stamps of the stages that wrote them."""
    check_stamped(run_dir, scene_id, CONTRACT[stage].reads)


def stamped_places(run_dir: Path, scene_id: str, *, besides: str | None = None) -> list[Place]:
    """Every place a stamped stage of the scene wrote (but `besides`'s own): what validate and verify check."""
    return [p for s in CONTRACT if s != besides and read_stamp(run_dir, scene_id, s) is not None
            for p in CONTRACT[s].writes]
