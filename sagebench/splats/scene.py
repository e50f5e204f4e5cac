"""A scene's Gaussians: its trained gaussians.ply with nearest-surface instance ids (or the ids it carries, as an
imported InteriorGS scene's does), else mesh samples.

Every object kind is kept (walls, floors and ceilings too: the agent's camera sees them) and every
Gaussian carries its object's instance id. Optional contribution pruning over views from inside the rooms.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator

import numpy as np
import shapely
from shapely.geometry import Polygon

from sagebench import ui
from sagebench.errors import DataError, SceneError
from sagebench.render.camera import Camera, agent_camera
from sagebench.render.gaussians import Gaussians, concat
from sagebench.scene.loader import SCENE_FILE, LoadedScene, frame_matrix, parse_spec
from sagebench.settings.build_scene import SplatConfig
from sagebench.settings.shared import CameraConfig
from sagebench.splats.assign import assign_instances
from sagebench.splats.from_mesh import mesh_gaussians, rotmat_to_quat
from sagebench.splats.ply import read_ply
from sagebench.splats.prune import PruneReport, prune

TRAINED_FILES = ("gaussians.ply", "3dgs_compressed.ply")  # looked for in the scene directory, in this order
STRUCTURE_KINDS = frozenset({"wall", "floor", "ceiling"})


def trained_gaussians(scene: LoadedScene) -> Gaussians | None:
    """The scene directory's trained Gaussians in world space (m, Z up), or None when it has none.

    A file that is a link leaving the scene directory, unreadable, malformed, non-finite or empty is a DataError,
    and so is one whose `instance_id`s name objects the scene does not have.
    """
    present = [scene.source_dir / name for name in TRAINED_FILES if os.path.lexists(scene.source_dir / name)]
    path = present[0] if present else None
    if path is None:
        return None
    if path.is_dir() or not path.exists():  # a directory or a dangling link is a mistake, not "no trained Gaussians"
        raise DataError("is not a PLY file (a directory or a broken link)", path=path)
    if not path.resolve().is_relative_to(scene.source_dir.resolve()):
        raise DataError("a link that leaves the scene directory", path=path)
    g = read_ply(path)
    if g.count == 0:
        raise DataError("holds no Gaussians", path=path, field="vertex")
    unknown = np.setdiff1d(g.instance_id, [0, *(o.instance_id for o in scene.spec.objects)])
    if len(unknown):
        raise DataError(f"instance_id {int(unknown[0])} is no object of the scene ({len(unknown)} such ids)",
                        path=path, field="instance_id")
    return _to_world(g, scene)


def scene_gaussians(scene: LoadedScene, config: SplatConfig = SplatConfig(), *, seed: int = 0,
                    camera: CameraConfig = CameraConfig(),
                    trained: Gaussians | None = None) -> tuple[Gaussians, PruneReport | None]:
    """The scene's Gaussians in world space (m, Z up) with instance ids, and the pruning report if pruned.

    `trained` is trained_gaussians(scene), read by the caller when it checks the scene; None samples the meshes.
    Trained Gaussians that carry instance ids keep them; others get the id of the nearest surface.
    """
    if trained is not None and trained.instance_id.any():
        g = trained
    elif trained is not None:
        g = trained
        ids = assign_instances(g.means, scene.meshes, tolerance=config.assign_tolerance)
        g = Gaussians(g.means, g.quats_wxyz, g.log_scales, g.opacity_logits, g.sh, ids)
    else:
        g = sampled_gaussians(scene, config, seed=seed)
    if config.prune == 0.0:
        return g, None
    views = list(room_views(scene, config.prune_views * 5 // 4, seed=seed, camera=camera, width=config.prune_width))
    cut = config.prune_views
    return prune(g, config.prune, views[:cut], views[cut:])


def sampled_gaussians(scene: LoadedScene, config: SplatConfig = SplatConfig(), *, seed: int = 0) -> Gaussians:
    """Flat Gaussians sampled on every object's world mesh; object i uses the seed (seed, instance_id)."""
    parts = []
    rooms = _room_space(scene) if config.cull_unseen else None
    for obj in ui.track(scene.spec.objects, "sampling Gaussians"):
        mesh = scene.meshes[obj.instance_id]
        structure = obj.kind in STRUCTURE_KINDS
        density = config.structure_density if structure else config.object_density
        faces = _faces_towards(mesh, rooms) if structure and rooms is not None else None
        parts.append(mesh_gaussians(
            mesh, obj.instance_id, spacing=1.0 / math.sqrt(density), faces=faces,
            rng=np.random.default_rng([seed, obj.instance_id]), scale_factor=config.scale_factor,
            thickness_ratio=config.thickness_ratio, opacity=config.opacity, shading=config.shading,
        ))
    return concat(parts)


def _room_space(scene: LoadedScene) -> tuple[shapely.Geometry, float, float] | None:
    """The rooms' floor area and the height range above it, or None for a scene without rooms."""
    if not scene.spec.rooms:
        return None
    top = max(float(m.bounds[1][2]) for m in scene.meshes.values())
    return shapely.unary_union([Polygon(r.polygon) for r in scene.spec.rooms]), scene.spec.floor_height, top


def _faces_towards(mesh, rooms: tuple[shapely.Geometry, float, float], step: float = 0.05) -> np.ndarray:
    """[F] bool: faces whose centre, moved `step` m along the normal, is inside a room (someone can see them).

    Drops the undersides of floor slabs, the tops of ceiling slabs and the outer faces of exterior walls.
    """
    area, z0, z1 = rooms
    probe = mesh.triangles_center + step * mesh.face_normals
    return shapely.contains_xy(area, probe[:, 0], probe[:, 1]) & (probe[:, 2] > z0) & (probe[:, 2] < z1)


def _to_world(g: Gaussians, scene: LoadedScene) -> Gaussians:
    """Trained Gaussians are in the artist scene's own units and up axis, like its meshes."""
    spec_path = scene.source_dir / SCENE_FILE
    try:
        raw = parse_spec(spec_path.read_text(encoding="utf-8"), spec_path)
    except OSError as err:
        raise SceneError(f"cannot read: {err.strerror}", path=spec_path) from None
    frame = frame_matrix(raw.units, raw.up_axis)
    scale = float(np.cbrt(np.linalg.det(frame[:3, :3])))
    rot = frame[:3, :3] / scale
    if np.allclose(rot, np.eye(3)):
        if scale == 1.0:
            return g
        quats, sh = g.quats_wxyz, g.sh
    else:
        quats = quat_multiply(rotmat_to_quat(rot[None])[0], g.quats_wxyz.astype(np.float64)).astype(np.float32)
        if g.sh_degree > 0:
            ui.warn(f"{scene.spec.scene_id}: trained Gaussians turned to Z up; their view-dependent colour "
                    f"(SH degree {g.sh_degree}) is dropped, the base colour kept")
        sh = g.sh[:, :1, :]
    means = (g.means.astype(np.float64) @ frame[:3, :3].T + frame[:3, 3]).astype(np.float32)
    log_scales = (g.log_scales + np.float32(math.log(scale))).astype(np.float32)
    return Gaussians(means, quats, log_scales, g.opacity_logits, np.ascontiguousarray(sh), g.instance_id)


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b of wxyz quaternions ([4] or [N, 4], broadcast)."""
    aw, ax, ay, az = np.moveaxis(np.broadcast_to(a, np.broadcast_shapes(a.shape, b.shape)), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.broadcast_to(b, np.broadcast_shapes(a.shape, b.shape)), -1, 0)
    return np.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], axis=-1)


def room_views(scene: LoadedScene, count: int, *, seed: int, camera: CameraConfig = CameraConfig(),
               width: int = 320) -> Iterator[Camera]:
    """`count` agent cameras at random points inside the rooms' floor polygons, random yaw, level."""
    rng = np.random.default_rng([seed, 6])
    rooms = [Polygon(r.polygon) for r in scene.spec.rooms]
    if not rooms:
        lo = np.min([m.bounds[0] for m in scene.meshes.values()], axis=0)
        hi = np.max([m.bounds[1] for m in scene.meshes.values()], axis=0)
        rooms = [shapely.box(lo[0], lo[1], hi[0], hi[1])]
    area = shapely.unary_union(rooms)
    x0, y0, x1, y1 = area.bounds
    made = 0
    while made < count:
        xy = rng.uniform([x0, y0], [x1, y1], size=(4 * count, 2))
        yaws = rng.uniform(-math.pi, math.pi, size=len(xy))
        for (x, y), yaw in zip(xy[shapely.contains_xy(area, xy[:, 0], xy[:, 1])], yaws):
            if made == count:
                break
            made += 1
            yield agent_camera(float(x), float(y), float(yaw), floor_z=scene.spec.floor_height,
                               camera_height=camera.height, hfov_deg=camera.hfov_deg,
                               width=width, height=width * 3 // 4)
