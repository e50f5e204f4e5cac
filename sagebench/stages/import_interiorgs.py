"""`import-interiorgs`: an InteriorGS scene folder -> a sagebench scene directory that build-scene and run take.

Reads SRC/3dgs_compressed.ply (or 3dgs.ply), labels.json, structure.json, occupancy.png and occupancy.json, and
a SAGE-3D collision USD when given. Writes OUT/scene.json, OUT/meshes/*.ply, OUT/gaussians.ply (with instance
ids), OUT/interiorgs_import.json (what was matched, the shares, the occupancy agreement) and
OUT/occupancy_check.png, all at once (a staged directory renamed into place).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from sagebench.config import from_options
from sagebench.errors import ConfigError
from sagebench.fileio import staged_dir
from sagebench.importers.config import REPORT_FILE, InteriorGSConfig
from sagebench.run_layout import SCENE_FILE

OPTIONS = {"--voxel": "voxel", "--min-opacity": "min_opacity", "--max-parts": "max_parts"}


def make_config(**fields: object) -> InteriorGSConfig:
    return from_options(InteriorGSConfig, fields, OPTIONS)


@dataclass(frozen=True)
class ImportResult:
    out_dir: Path
    report: dict
    warnings: tuple[str, ...]

    def summary(self) -> str:
        r = self.report
        s = r["shares"]
        return (f"import-interiorgs {r['scene_id']}: {r['objects']} objects from {r['labels']} labels, {r['rooms']} "
                f"rooms, {r['walls']} walls, {len(r['doors'])} doors, {r['gaussians']:,} Gaussians "
                f"({s['object_boxes']:.1%} in object boxes, {s['structure']:.1%} on walls, floors and ceilings, "
                f"{s['background']:.1%} background), occupancy.png agreement {r['occupancy_iou']:.3f} IoU -> {self.out_dir}")


def import_interiorgs_scene(src: Path, out: Path, config: InteriorGSConfig = InteriorGSConfig(), *,
                            collision_usd: Path | None = None, force: bool = False) -> ImportResult:
    """Import `src` into `out` (absent, empty or an earlier import, unless `force`)."""
    from sagebench.importers.interiorgs import import_interiorgs, write_imported

    if not force:
        _check_replaceable(Path(out))
    if collision_usd is not None and not Path(collision_usd).is_file():
        raise ConfigError("no such file", path=collision_usd, field="--collision-usd")
    imported = import_interiorgs(Path(src), config, collision_usd=collision_usd)
    with staged_dir(Path(out)) as tmp:
        write_imported(imported, tmp)
    return ImportResult(Path(out), imported.report, imported.warnings)


def _check_replaceable(out: Path) -> None:
    if not out.exists() and not out.is_symlink():
        return
    if out.is_symlink() or not out.is_dir():
        raise ConfigError("exists and is not a directory; choose another --out (or --force to replace it)",
                          path=out, field="--out")
    if not any(out.iterdir()):
        return
    try:
        ours = json.loads((out / REPORT_FILE).read_text(encoding="utf-8")).get("scene_id") is not None
    except (OSError, ValueError, AttributeError):
        ours = False
    if not (ours and (out / SCENE_FILE).is_file()):
        raise ConfigError("is not empty and not a scene written by `sagebench import-interiorgs`; choose another "
                          "--out (or --force to replace it)", path=out, field="--out")
