"""`build-scene`: a scene directory -> RUN/scenes/<scene_id>/ with the normalised scene and its top-down maps.

Writes scene.json + meshes (normalised, loadable with `load_scene`), topdown.npz, semantic_map.json,
topdown.png and gaussians.ply (3DGS with instance ids), all at once (a staged directory renamed into place).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from sagebench.fileio import dumps_json, staged_dir, write_bytes
from sagebench.run_layout import GAUSSIANS, SEMANTIC_MAP, TOPDOWN, TOPDOWN_PNG, run_scene_dir
from sagebench.scene.checks import check_floor_known
from sagebench.scene.loader import SCENE_FILE, LoadedScene, load_scene, write_normalised_scene
from sagebench.settings.build_scene import BuildSceneConfig

if TYPE_CHECKING:
    from sagebench.render.gaussians import Gaussians
    from sagebench.splats.prune import PruneReport
    from sagebench.topdown.raster import Grid
    from sagebench.topdown.semantic_map import RoomReach


@dataclass(frozen=True)
class BuildSceneResult:
    scene_id: str
    out_dir: Path  # RUN/scenes/<scene_id>
    shape: tuple[int, int]  # (H, W) cells
    resolution: float
    navigable_area_m2: float
    rooms: int
    room_reach: tuple[RoomReach, ...]  # per room: reachable, navigable area and the part outside the main region
    all_rooms_connected: bool
    gaussians: int
    pruned: PruneReport | None

    @property
    def rooms_reachable(self) -> int:
        """Rooms with more than half their navigable area in the main region."""
        return sum(r.reachable for r in self.room_reach)

    def summary(self) -> str:
        h, w = self.shape
        prune = "" if self.pruned is None else (
            f" (pruned {self.pruned.fraction:.0%} of {self.pruned.count_before}: held-out PSNR "
            f"{self.pruned.psnr_db:.1f} dB)")
        cut = [f"{r.room_id} {r.unreachable_area_m2:.2f} of {r.navigable_area_m2:.2f} m^2"
               + ("" if r.reachable else " (unreachable)") for r in self.room_reach if r.unreachable_area_m2 > 0 or not r.reachable]
        cut = f" (navigable floor outside the main region: {', '.join(cut)})" if cut else ""
        return (
            f"build-scene {self.scene_id}: map {w}x{h} cells at {self.resolution:g} m, "
            f"navigable {self.navigable_area_m2:.1f} m^2, {self.rooms_reachable}/{self.rooms} rooms "
            f"reachable{cut}, {self.gaussians} Gaussians{prune} -> {self.out_dir}"
        )


@dataclass(frozen=True)
class CheckedScene:
    """A scene that build-scene would accept: loaded, its map within the cell budget, its trained Gaussians read."""

    scene: LoadedScene
    trained: Gaussians | None  # world space; None when the scene directory has no trained gaussians.ply
    grid: Grid  # covering every mesh and room at the configured resolution


def check_scene(scene_dir: Path, config: BuildSceneConfig | None = None) -> CheckedScene:
    """Everything build-scene refuses, without building (`check-scene`). An InteriorGS folder is imported into a
    temporary directory first, gone when this returns (the checked scene is in memory)."""
    from sagebench.importers.source import opened_scene

    with opened_scene(scene_dir, config or BuildSceneConfig()) as source:
        return _check(source, config)


def _check(scene_dir: Path, config: BuildSceneConfig | None = None) -> CheckedScene:
    scene = load_scene(scene_dir)  # a bad scene.json is refused before the map and splat code is even imported
    check_floor_known(scene.spec, [np.asarray(scene.meshes[o.instance_id].triangles) for o in scene.spec.objects
                                   if o.kind == "floor"], scene_dir / SCENE_FILE)
    from sagebench.splats.scene import trained_gaussians
    from sagebench.topdown.builder import scene_grid

    grid = scene_grid(scene, (config or BuildSceneConfig()).resolution)
    return CheckedScene(scene=scene, trained=trained_gaussians(scene), grid=grid)


def build_scene(scene_dir: Path, run_dir: Path, config: BuildSceneConfig | None = None) -> BuildSceneResult:
    """Check `scene_dir` (a scene directory or an InteriorGS folder, imported first), compute its top-down maps and
    Gaussians and write RUN/scenes/<scene_id>/ atomically."""
    from sagebench.importers.source import opened_scene

    config = config or BuildSceneConfig()
    with opened_scene(scene_dir, config) as source:
        return _build(_check(source, config), run_dir, config)


def _build(checked: CheckedScene, run_dir: Path, config: BuildSceneConfig) -> BuildSceneResult:
    from sagebench.splats.ply import write_ply
    from sagebench.splats.scene import scene_gaussians
    from sagebench.topdown.builder import compute_topdown
    from sagebench.topdown.grid_file import topdown_bytes
    from sagebench.topdown.render_png import render_topdown

    scene = checked.scene
    td = compute_topdown(scene, config)
    png = render_topdown(td)
    gaussians, pruned = scene_gaussians(scene, config.splats, seed=config.seed, camera=config.camera,
                                        trained=checked.trained)
    out = run_scene_dir(run_dir, scene.spec.scene_id)
    with staged_dir(out) as tmp:
        write_normalised_scene(scene, tmp)
        write_bytes(tmp / TOPDOWN, topdown_bytes(td))
        write_bytes(tmp / SEMANTIC_MAP, dumps_json(td.semantic.model_dump(mode="json")).encode())
        write_bytes(tmp / TOPDOWN_PNG, png)
        write_ply(tmp / GAUSSIANS, gaussians)
    return BuildSceneResult(
        scene_id=scene.spec.scene_id,
        out_dir=out,
        shape=td.grid.shape,
        resolution=td.grid.resolution,
        navigable_area_m2=td.semantic.navigable_area_m2,
        rooms=len(scene.spec.rooms),
        room_reach=tuple(td.semantic.rooms),
        all_rooms_connected=td.semantic.all_rooms_connected,
        gaussians=gaussians.count,
        pruned=pruned,
    )
