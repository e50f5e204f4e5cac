"""The ways to turn one concave piece into convex parts, and which of them each `--colliders` mode tries.

- `hull`: the piece's convex hull (one part; right for handles, cushions, anything whose notches the agent
  cannot reach);
- `voxel`: boxes covering a voxelisation (collider_export/voxel.py; any mesh, about a second);
- `coacd`: CoACD on the piece with its holes closed first (repair.py), so its remeshing preprocess is
  skipped, capped at the part budget, on one thread (its parallel loop collects parts in the order its threads
  finish them, so two threads gave other parts when the machine was busy).

Every mode keeps the first of its methods whose agent-band footprint is within the tolerance of the
piece's (quality.band_errors), else the best of them. `fast` and `balanced` try the cheapest first;
`quality` tries CoACD first (fewer parts that follow the surface), then the voxel parts: on the bench scene
CoACD after hole closing was once 84 cm off in the band (pymeshfix dropped half a cushion), which the
measure catches. Which methods a piece gets depends on the piece alone, never on the clock: CoACD, whose
work grows with the faces it cuts, is left out for pieces of more than `coacd_max_faces` faces (`ladder`).
A piece that every method of its mode leaves outside the tolerance escalates (ESCALATIONS): `balanced` and
`quality` to `coacd_fine` (CoACD at 0.4 of the threshold, resolution 2000, up to the part budget whatever
--coacd-max-hulls says), every mode last to `voxel_exact` (voxels of half the tolerance, their boxes merged only
down to the larger last-resort budget --exact-max-parts: at the 32-part budget they were 19 cm off on an open C,
at 128 parts 1 cm); the piece keeps the closest of all, and colliders.json names the method it ended with. V-HACD (the vhacdx package) was measured and left out: on the 19 bench pieces whose hull misses the band it
always used its 32 hulls, 11 of them within 2 cm (voxel 17, CoACD 16) in 3x the voxel time.
"""

from __future__ import annotations

from typing import Literal

import numpy as np

from sagebench.collider_export.coacd_cache import run_coacd
from sagebench.collider_export.convex import ConvexPart, hull_part
from sagebench.collider_export.quality import band_errors
from sagebench.collider_export.repair import close_holes
from sagebench.collider_export.voxel import voxel_parts
from sagebench.settings.export_usd import ColliderSettings

Method = Literal["hull", "voxel", "coacd", "coacd_fine", "voxel_exact"]
UNSHAPING = frozenset({"piece_limit_s"})  # ColliderSettings fields that never change the parts

LADDERS: dict[str, tuple[Method, ...]] = {
    "fast": ("hull", "voxel"),
    "balanced": ("hull", "voxel", "coacd"),
    "quality": ("coacd", "voxel", "hull"),
}


# tried, in this order, only by a piece that every method of its mode left outside the band tolerance (open
# concave furniture: an open C of 270 degrees was 3.2 cm off by CoACD and 3.0 by voxels, 1.0 by coacd_fine and by
# voxel_exact); `fast` never runs CoACD
ESCALATIONS: dict[str, tuple[Method, ...]] = {
    "fast": ("voxel_exact",),
    "balanced": ("coacd_fine", "voxel_exact"),
    "quality": ("coacd_fine", "voxel_exact"),
}
FINE_THRESHOLD = 0.4  # coacd_fine's concavity threshold, as a share of --coacd-threshold
FINE_RESOLUTION = 2000  # coacd_fine's sampling resolution (CoACD's own default)
EXACT_PITCH_MIN = 0.01  # m, voxel_exact's finest voxels (voxel_pitch's least): a piece's cells grow as 1 / pitch^3


def ladder(settings: ColliderSettings, faces: int) -> tuple[Method, ...]:
    """The methods a piece of `faces` faces tries, in order: its mode's, then the escalation's finer ones; CoACD's
    left out above coacd_max_faces."""
    return tuple(m for m in (*LADDERS[settings.mode], *ESCALATIONS[settings.mode])
                 if not m.startswith("coacd") or faces <= settings.coacd_max_faces)


def part_budget(method: str, settings: ColliderSettings) -> int:
    """The most parts a piece's `method` may give, and an object with a piece that ended with it may keep."""
    return max(settings.exact_max_parts, settings.max_parts) if method == "voxel_exact" else settings.max_parts


def exact_pitch(settings: ColliderSettings) -> float:
    """voxel_exact's voxel size, m: half the band tolerance, no finer than EXACT_PITCH_MIN."""
    return max(settings.band_tolerance_cm / 200, EXACT_PITCH_MIN)


def run_method(method: Method, vertices: np.ndarray, faces: np.ndarray, settings: ColliderSettings,
               band: tuple[float, float]) -> list[ConvexPart]:
    """Convex parts of one piece (vertices [V, 3] m, faces [F, 3]) by `method`, the agent's band (bottom, top) as z
    in the piece's frame; raises when the method fails."""
    if method == "hull":
        return [hull_part(vertices)]
    if method in ("voxel", "voxel_exact"):
        # the voxel footprint is a pitch coarse: a box within tolerance of it may reach half a cell farther
        pitch = settings.voxel_pitch if method == "voxel" else exact_pitch(settings)
        return voxel_parts(vertices, faces, pitch=pitch, max_parts=part_budget(method, settings), band=band,
                           tolerance=max(settings.band_tolerance_cm / 100 - pitch / 2, 0.0))
    closed = close_holes(vertices, faces)
    if closed is None:
        raise RuntimeError("its holes could not be closed")
    cap = settings.max_parts if settings.coacd.max_convex_hull < 0 else min(settings.coacd.max_convex_hull,
                                                                            settings.max_parts)
    fine = {"threshold": settings.coacd.threshold * FINE_THRESHOLD, "resolution": FINE_RESOLUTION,
            "max_convex_hull": settings.max_parts} if method == "coacd_fine" else {}
    params = settings.coacd.model_copy(update={"max_convex_hull": cap, **fine})
    return [hull_part(v) for v, _ in run_coacd(*closed, params, threads=1)]


def band_error_cm(vertices: np.ndarray, faces: np.ndarray, parts: list[ConvexPart], band: tuple[float, float]) -> float:
    """The worse of the band over/under figures (cm) of `parts` against the piece, in the agent's band (z, m)."""
    import trimesh

    source = trimesh.Trimesh(np.asarray(vertices, dtype=np.float64), np.asarray(faces, dtype=np.int64), process=False)
    return 100.0 * max(band_errors(source, parts, band, 0.01))


def good_enough(error_cm: float, settings: ColliderSettings) -> bool:
    """Stop the ladder here: the band error is within tolerance."""
    return error_cm <= settings.band_tolerance_cm
