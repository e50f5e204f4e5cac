"""`import-interiorgs`: an InteriorGS scene folder -> a sagebench scene directory that build-scene and run take.

Reads SRC/3dgs_compressed.ply (or 3dgs.ply), labels.json, structure.json, occupancy.png and occupancy.json, and
a SAGE-3D collision USD when given. Writes OUT/scene.json, OUT/meshes/*.ply, OUT/gaussians.ply (with instance
ids), OUT/interiorgs_import.json (what was matched, the shares, the surface noise, the occupancy agreement) and
OUT/occupancy_check.png, all at once (a staged directory renamed into place).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from sagebench.errors import ConfigError
from sagebench.fileio import staged_dir
from sagebench.importers.config import REPORT_FILE
from sagebench.input_files import read_regular
from sagebench.run_folder import check_scene_out
from sagebench.run_layout import SCENE_FILE
from sagebench.settings.import_interiorgs import InteriorGSConfig


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
                f"({r['floaters_dropped']:,} floaters dropped; "
                f"{s['object_boxes']:.1%} in object boxes, {s['structure']:.1%} on walls, floors and ceilings, "
                f"{s['background']:.1%} background), surface noise {_cm(r['surface_noise_m'])}, unlabelled obstacles: "
                f"{len(r['unlabelled'])} ({sum(u['area_m2'] for u in r['unlabelled'].values()):.2f} m^2), occupancy.png agreement {r['occupancy_iou']:.3f} IoU -> {self.out_dir}")


def _cm(metres: float | None) -> str:
    return "unmeasured" if metres is None else f"{metres * 100:.2f} cm"


def import_interiorgs_scene(src: Path, out: Path, config: InteriorGSConfig = InteriorGSConfig(), *,
                            collision_usd: Path | None = None, force: bool = False) -> ImportResult:
    """Import `src` into `out` (absent, empty or an earlier import, unless `force`; never an input, inside one or
    holding one: run_folder.check_scene_out)."""
    from sagebench.importers.interiorgs import import_interiorgs, write_imported

    check_scene_out(Path(out), "import-interiorgs", ours=_is_import, force=force,
                    inputs={"SRC": src, "--collision-usd": collision_usd})
    if collision_usd is not None and not Path(collision_usd).is_file():
        raise ConfigError("no such file", path=collision_usd, field="--collision-usd")
    imported = import_interiorgs(Path(src), config, collision_usd=collision_usd)
    with staged_dir(Path(out)) as tmp:
        write_imported(imported, tmp)
    return ImportResult(Path(out), imported.report, imported.warnings)


def _is_import(out: Path) -> bool:
    """Whether `out` holds a scene import-interiorgs wrote (its report and a scene.json)."""
    try:
        ours = json.loads(read_regular(out / REPORT_FILE, limit=1 << 26) or b"").get("scene_id") is not None
    except (ValueError, AttributeError):
        ours = False
    return ours and (out / SCENE_FILE).is_file()
