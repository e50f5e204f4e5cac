"""`export-sage`: a run's episodes as SAGE-3D GVLN trajectory files, one per scene (sagebench.gvln.episodes).

Reads RUN/episodes/<id>/part-*.parquet and RUN/scenes/<id>/scene.json. Writes OUT/<id>/trajectories_<id>.json
per scene (the name SAGE-3D's trajectory generator gives its files) and OUT/sage_export.json (what was
exported: the mark of an export-sage folder, which a later export-sage may write again). Everything is
computed before the first byte is written; the run is not changed.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pyarrow as pa

from sagebench.episodes.shards import read_episodes
from sagebench.errors import DataError
from sagebench.fileio import dumps_json, write_text
from sagebench.gvln.episodes import gvln_document
from sagebench.run_layout import CONTRACT, SCENE_FILE, require, run_episodes_dir, run_scene_dir, run_scenes
from sagebench.scene.loader import parse_spec


MARKER = "sage_export.json"


def gvln_file(scene_id: str) -> str:
    return f"{scene_id}/trajectories_{scene_id}.json"


@dataclass(frozen=True)
class SageExport:
    out_dir: Path
    files: dict[str, tuple[int, int]]  # scene id -> (trajectories, instructions)

    def lines(self) -> list[str]:
        t = sum(v[0] for v in self.files.values())
        i = sum(v[1] for v in self.files.values())
        return [f"export-sage: {t} trajectories, {i} instructions, {len(self.files)} scene(s) -> {self.out_dir}"]


def export_sage(run_dir: Path, out_dir: Path, *, scene_id: str | None = None) -> SageExport:
    """Write every scene's (or `scene_id`'s) episodes as a GVLN file under `out_dir`."""
    docs = {}
    for sid in run_scenes(Path(run_dir), scene_id, having="episodes"):
        require(CONTRACT["export_sage"].reads, run_dir, sid)
        try:
            rows = read_episodes(run_episodes_dir(run_dir, sid)).to_pylist()
        except (OSError, pa.ArrowException) as err:
            raise DataError(f"cannot read episode shards: {err}", path=run_episodes_dir(run_dir, sid)) from None
        spec_path = run_scene_dir(run_dir, sid) / SCENE_FILE
        spec = parse_spec(spec_path.read_text(encoding="utf-8"), spec_path)
        docs[sid] = gvln_document(sid, rows, spec)
    counts = {sid: (len(d["scenes"][0]["samples"]), sum(len(s["instructions"]) for s in d["scenes"][0]["samples"]))
              for sid, d in docs.items()}
    for sid, doc in docs.items():
        write_text(Path(out_dir) / gvln_file(sid), dumps_json(doc))
    write_text(Path(out_dir) / MARKER, dumps_json({
        "format": 1, "files": {sid: {"file": gvln_file(sid), "trajectories": t, "instructions": i}
                               for sid, (t, i) in counts.items()}}))
    return SageExport(Path(out_dir), counts)
