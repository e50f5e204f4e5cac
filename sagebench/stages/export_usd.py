"""`export-usd`: RUN/scenes/<id>/ -> colliders/ (convex parts), scene.usda + geometry.usdc (3DGS, colliders,
semantics), scene.xml, and with --usdz scene.usdz (with --gaussians nurec gaussians.usdz, with --layout sage sage/).

Reads the normalised scene (scene.json + meshes) and gaussians.ply that build-scene wrote. Writes
colliders/<category>_<instance_id>/part_NNN.stl (world frame) and colliders/colliders.json, then
geometry.usdc, scene.usda (which references it), scene.usdz and scene.xml; all are computed before the
first byte is written.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from sagebench import ui
from sagebench.collider_export.coacd_cache import PartCache, PieceResult
from sagebench.collider_export.free_floor import FloorMap
from sagebench.collider_export.pieces import Piece, decompose_pieces
from sagebench.collider_export.scene_export import ExportResult, build_export, plan_scene_pieces
from sagebench.fileio import staged_dir, write_bytes, write_text
from sagebench.render.gaussians import Gaussians
from sagebench.run_layout import (COLLIDERS, GAUSSIANS, MJCF, NUREC, SAGE, SEMANTIC_MAP, TOPDOWN, USDZ, run_scene_dir,
                                   run_scenes)
from sagebench.scene.loader import load_scene
from sagebench.settings.export_usd import ColliderSettings, ExportConfig
from sagebench.topdown.grid_file import read_topdown_grids
from sagebench.topdown.semantic_map import read_semantic_map


def default_cache_dir() -> Path:
    import platformdirs

    return Path(platformdirs.user_cache_dir("sagebench"))


def export_usd(
    run_dir: Path, *, scene_id: str | None = None, config: ExportConfig = ExportConfig(), cache_dir: Path | None = None
) -> list[ExportResult]:
    """Export every scene of the run (or `scene_id`); CoACD results are cached in `cache_dir`
    (default: the user cache directory)."""
    cache = part_cache(cache_dir)
    return [export_scene(run_scene_dir(run_dir, sid), config=config, cache=cache)
            for sid in run_scenes(run_dir, scene_id)]


def part_cache(cache_dir: Path | None) -> PartCache:
    """The piece cache in `cache_dir`, or in the user cache directory when None."""
    return PartCache(default_cache_dir() if cache_dir is None else cache_dir)


def scene_pieces(run_dir: Path, scene_id: str, config: ExportConfig,
                 cache: PartCache) -> tuple[list[tuple[Piece, ColliderSettings]], tuple[float, float]]:
    """The concave pieces export_scene would decompose for the scene, each with the settings of its pass, and the
    agent band they are judged in."""
    (sid,) = run_scenes(run_dir, scene_id)
    scene_dir = run_scene_dir(run_dir, sid)
    return plan_scene_pieces(load_scene(scene_dir), config, cache), agent_band(scene_dir)


def agent_band(scene_dir: Path) -> tuple[float, float]:
    """The world z band (floor + the agent's clearance .. floor + its height) the scene's map was built for:
    the colliders are judged in the band the map blocks."""
    low, high = read_semantic_map(scene_dir / SEMANTIC_MAP).band_m
    return low, high


def decompose_piece(piece: Piece, colliders: ColliderSettings, band: tuple[float, float],
                    cache_dir: Path | None) -> PieceResult:
    """One piece as export_scene's pass with `colliders` makes it (methods, safety limit, cache), without
    progress lines."""
    (result,) = decompose_pieces([piece], colliders, cache=part_cache(cache_dir), band=band, progress=False)
    return result


def export_scene(scene_dir: Path, *, config: ExportConfig, cache: PartCache) -> ExportResult:
    """Export one built scene: everything is computed before the first byte is written."""
    made = build_export(load_scene(scene_dir), _read_gaussians(scene_dir / GAUSSIANS), _floor_map(scene_dir),
                        band=agent_band(scene_dir), config=config, cache=cache)
    with staged_dir(scene_dir / COLLIDERS) as tmp:
        for rel, data in made.colliders.items():
            write_bytes(tmp / rel, data)
    _write_usd_files(scene_dir, made.usd)
    write_text(scene_dir / MJCF, made.mjcf)
    return made.result


def _write_usd_files(scene_dir: Path, files: dict[str, bytes]) -> None:
    """Write `files` (SceneExport.usd) in order, sage/ as one directory, and remove what a previous export with
    other options wrote and this one did not."""
    sage = {rel: data for rel, data in files.items() if rel.startswith(f"{SAGE}/")}
    for rel, data in files.items():
        if rel not in sage:
            write_bytes(scene_dir / rel, data)
    if sage:
        with staged_dir(scene_dir / SAGE) as tmp:
            for rel, data in sage.items():
                write_bytes(tmp / Path(rel).name, data)
    else:
        shutil.rmtree(scene_dir / SAGE, ignore_errors=True)
    for name in (USDZ, NUREC):
        if name not in files:
            (scene_dir / name).unlink(missing_ok=True)


def _floor_map(scene_dir: Path) -> FloorMap | None:
    """The occupancy build-scene wrote, which the colliders must leave free; None for a scene without a
    topdown.npz (written by other means: the band warnings are all there is then)."""
    if not (scene_dir / TOPDOWN).is_file():
        return None
    grids = read_topdown_grids(scene_dir / TOPDOWN)
    return FloorMap(grids.occupancy, grids.resolution, grids.origin)


def _read_gaussians(path: Path) -> Gaussians | None:
    """The scene's gaussians.ply; None (with a warning) without the file."""
    if not path.is_file():
        ui.warn(f"{path}: not found; the stage gets colliders and semantics but no Gaussians")
        return None
    from sagebench.splats.ply import read_ply

    return read_ply(path)
