"""Test fixtures only: a sagebench scene written as an InteriorGS scene folder, following the dataset card
(manycore-research/InteriorGS) and SAGE-3D's consumer code (Galery23/SAGE-3D_Official), not sagebench's reader.

- 3dgs_compressed.ply: Gaussians sampled on the meshes, *without* instance ids, in SuperSplat's compressed layout
  as PlayCanvas's splat-transform writes it (Morton-ordered chunks of 256, 18 float chunk bounds, packed
  position/scale 11-10-11 normalised within the chunk, rotation as the largest component's index and the other
  three in 10 bits each scaled by sqrt(2)/2 around 0.5 with the largest made positive, colour 8-8-8 within the
  chunk's colour range and opacity as a byte, SH bands as bytes of v / 8 + 0.5); or 3dgs.ply in the INRIA layout.
- labels.json: a list of {ins_id, label, bounding_box}; the box is the object's tightest box turned about Z
  (minimum-area rectangle of its outline), its 8 corners {x, y, z}: the bottom face counter-clockwise, then the
  top face (SAGE's semantic_map_builder takes the first four as the footprint polygon); walls, floors and
  ceilings are labelled too.
- structure.json: rooms (profile, room_type in InteriorGS's words), walls (centre-line location, thickness,
  height), holes (DOOR and WINDOW outlines on their walls), ins (label, position, size).
- occupancy.png/json: the 1.2 m band occupancy: 255 free floor, 0 objects, 127 walls and outside; `scale` m per
  pixel, `min`/`max` the corners; the image is the grid turned by 180 degrees (what SAGE's semantic map builder
  assumes: it flips the image up-down and draws boxes at (H - 1 - i, W - 1 - j)).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import shapely
import trimesh

from sagebench.render.gaussians import SH_C0, Gaussians
from sagebench.scene.loader import SCENE_FILE, LoadedScene, load_scene
from sagebench.scene.model import Transform
from sagebench.settings.build_scene import BuildSceneConfig, SplatConfig
from sagebench.splats.scene import sampled_gaussians
from sagebench.topdown.builder import Topdown, compute_topdown
from sagebench.topdown.footprints import mesh_parts
from sagebench.topdown.occupancy import band_occupancy
from sagebench.topdown.raster import Grid, polygon_mask

ROOM_NAMES = {"living_room": "Living and Dining Room", "bedroom": "Master Bedroom", "kitchen": "Kitchen",
              "study": "Study", "bathroom": "Bathroom"}
CHUNK = 256


@dataclass(frozen=True)
class Truth:
    """What the folder does not say: each written Gaussian's instance, each label's instance, the mesh maps."""

    scene: LoadedScene
    gaussian_ids: np.ndarray  # [N] instance id per Gaussian, in the PLY's order
    label_ids: list[int]  # instance id of labels.json[k]
    topdown: Topdown  # the mesh scene's maps at the default settings


def write_interiorgs_folder(scene_dir: Path, out: Path, *, splats: SplatConfig = SplatConfig(),
                            layout: str = "compressed", seed: int = 0) -> Truth:
    scene = load_scene(scene_dir)
    out.mkdir(parents=True, exist_ok=True)
    g = unseen_dropped(scene, sampled_gaussians(scene, splats, seed=seed))
    if layout == "compressed":
        order = morton_order(g.means)
        g = g.take(order)
        (out / "3dgs_compressed.ply").write_bytes(compressed_ply(g))
    else:
        (out / "3dgs.ply").write_bytes(inria_ply(g))
    labels, label_ids = [], []
    for obj in scene.spec.objects:
        labels.append({"ins_id": f"{obj.instance_id:06d}", "label": obj.category.replace("_", " "),
                       "bounding_box": [dict(zip("xyz", map(float, c))) for c in obb_corners(scene.meshes[obj.instance_id])]})
        label_ids.append(obj.instance_id)
    (out / "labels.json").write_text(json.dumps(labels, indent=1))
    (out / "structure.json").write_text(json.dumps(structure(scene, labels), indent=1))
    td = compute_topdown(scene, BuildSceneConfig())
    png, meta = occupancy(scene, td)
    (out / "occupancy.png").write_bytes(png)
    (out / "occupancy.json").write_text(json.dumps(meta))
    return Truth(scene, g.instance_id.copy(), label_ids, td)


def turned_scene(src: Path, dest: Path, yaw_deg: float) -> Path:
    """The scene in `src` turned by `yaw_deg` about Z around the middle of its rooms' box (which lands on the
    origin), written to `dest`: rooms, object transforms and door hinges turned, meshes copied as they are."""
    scene = load_scene(src)
    a = math.radians(yaw_deg)
    turn = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    corners = np.concatenate([np.asarray(r.polygon)[:, :2] for r in scene.spec.rooms])
    move = np.eye(4)
    move[:2, :2], move[:2, 3] = turn, -turn @ ((corners.min(axis=0) + corners.max(axis=0)) / 2)
    to = lambda x, y: tuple(float(v) for v in move[:2, :2] @ (x, y) + move[:2, 3])  # noqa: E731
    objects = []
    for o in scene.spec.objects:
        m = move @ o.transform.as_matrix()
        update = {"transform": Transform(matrix=tuple(tuple(float(v) for v in row) for row in m))}
        if o.door:
            update["door"] = o.door.model_copy(update={"hinge": (*to(*o.door.hinge[:2]), o.door.hinge[2])})
        objects.append(o.model_copy(update=update))
        (dest / o.mesh).parent.mkdir(parents=True, exist_ok=True)
        (dest / o.mesh).write_bytes((src / o.mesh).read_bytes())
    rooms = [r.model_copy(update={"polygon": [to(*p[:2]) for p in r.polygon]}) for r in scene.spec.rooms]
    spec = scene.spec.model_copy(update={"rooms": rooms, "objects": objects})
    (dest / SCENE_FILE).write_text(json.dumps(spec.model_dump(mode="json", exclude_defaults=True)))
    return dest


def unseen_dropped(scene: LoadedScene, g: Gaussians, contact: float = 0.005) -> Gaussians:
    """The Gaussians a camera could see in the InteriorGS version of the scene: no object bottom resting on the
    floor and no floor under it (a scene trained from renders has none there; sampling the meshes puts some),
    and no wall surface across a window (InteriorGS cuts a hole for it; the synth walls are solid behind it)."""
    kinds = {o.instance_id: o.kind for o in scene.spec.objects}
    structure = np.isin(g.instance_id, [i for i, k in kinds.items() if k in ("wall", "floor", "ceiling")])
    wall = np.isin(g.instance_id, [i for i, k in kinds.items() if k == "wall"])
    low = g.means[:, 2] < contact
    bottoms, glass = [], np.zeros(g.count, dtype=bool)
    for iid, kind in kinds.items():
        mesh = scene.meshes[iid]
        if kind == "window":
            rect = shapely.MultiPoint(mesh.vertices[:, :2]).convex_hull.minimum_rotated_rectangle
            z0, z1 = mesh.bounds[:, 2]
            across = shapely.contains_xy(rect.buffer(0.06, cap_style="flat", join_style="mitre", mitre_limit=10),
                                         g.means[:, 0], g.means[:, 1])
            glass |= across & (g.means[:, 2] > z0) & (g.means[:, 2] < z1)
        if kind in ("wall", "floor", "ceiling"):
            continue
        tri = mesh.triangles
        flat = (tri[:, :, 2] < contact).all(axis=1)
        bottoms += [shapely.Polygon(t[:, :2]) for t in tri[flat] if shapely.Polygon(t[:, :2]).area > 1e-9]
    under = shapely.contains_xy(shapely.union_all(bottoms), g.means[:, 0], g.means[:, 1]) if bottoms else False
    keep = ~(low & ~structure) & ~(low & structure & under) & ~(wall & glass)
    return g.take(np.flatnonzero(keep))


# ---------------------------------------------------------------- boxes and plan


def obb_corners(mesh: trimesh.Trimesh) -> np.ndarray:
    """[8, 3] corners of the mesh's tightest box turned about Z: bottom face counter-clockwise, then the top."""
    rect = shapely.MultiPoint(mesh.vertices[:, :2]).convex_hull.minimum_rotated_rectangle
    ring = np.asarray(shapely.orient_polygons(rect).exterior.coords)[:4]
    z0, z1 = mesh.bounds[:, 2]
    return np.array([[x, y, z] for z in (z0, z1) for x, y in ring])


def structure(scene: LoadedScene, labels: list[dict]) -> dict:
    spec = scene.spec
    rooms = [{"profile": [list(p) for p in r.polygon], "room_type": ROOM_NAMES[r.type]} for r in spec.rooms]
    walls, holes = [], []
    for obj in spec.objects:
        mesh = scene.meshes[obj.instance_id]
        if obj.kind == "wall":
            c = obb_corners(mesh)
            a, b, d = c[0, :2], c[1, :2], c[3, :2]
            (p, q), t = ((a, b), np.linalg.norm(d - a)) if np.linalg.norm(b - a) >= np.linalg.norm(d - a) else ((a, d), np.linalg.norm(b - a))
            u = (q - p) / np.linalg.norm(q - p)
            mid = (c[0, :2] + c[2, :2]) / 2
            half = np.linalg.norm(q - p) / 2 - t / 2  # the centre line ends half a thickness inside the mesh
            walls.append({"location": [list(mid - u * half), list(mid + u * half)], "thickness": float(t),
                          "height": float(mesh.bounds[1, 2])})
        elif obj.kind in ("door", "window"):
            m = obj.transform.as_matrix()
            u = m[:2, 0] / np.linalg.norm(m[:2, 0])  # the leaf's or pane's own x: along its wall when closed
            centre = m[:2, 3]
            if obj.kind == "door":
                from sagebench.scene.synth import DOOR_H, DOOR_W, WALL_T

                width, z0, z1, thick = DOOR_W, 0.0, DOOR_H, WALL_T
            else:
                along = mesh.vertices[:, :2] @ u
                width, z0, z1, thick = float(np.ptp(along)), float(mesh.bounds[0, 2]), float(mesh.bounds[1, 2]), 0.1
                centre = u * (along.min() + along.max()) / 2 + centre - u * (centre @ u)
            ends = [centre - u * width / 2, centre + u * width / 2]
            holes.append({"profile": [[*ends[0], z0], [*ends[1], z0], [*ends[1], z1], [*ends[0], z1]],
                          "thickness": thick, "type": obj.kind.upper()})
    ins = [{"label": lab["label"].title(), "position": np.mean([[v["x"], v["y"], v["z"]] for v in lab["bounding_box"]], axis=0).tolist(),
            "size": np.ptp([[v["x"], v["y"], v["z"]] for v in lab["bounding_box"]], axis=0).tolist()} for lab in labels]
    return {"rooms": rooms, "walls": walls, "holes": holes, "ins": ins}


def occupancy(scene: LoadedScene, td: Topdown) -> tuple[bytes, dict]:
    grid = td.grid
    inside = polygon_mask(shapely.union_all([shapely.Polygon(r.polygon) for r in scene.spec.rooms]), grid)
    kinds = {o.instance_id: o.kind for o in scene.spec.objects}
    wall = np.isin(td.instance, [i for i, k in kinds.items() if k == "wall"])
    values = np.full(grid.shape, 127, dtype=np.uint8)
    values[(td.occupancy == 0) & inside] = 255
    values[(td.occupancy != 0) & ~wall & inside] = 0
    ok, png = cv2.imencode(".png", np.ascontiguousarray(values[:, ::-1]))
    h, w = grid.shape
    x0, y0 = grid.origin
    top = max(float(m.bounds[1, 2]) for m in scene.meshes.values())
    meta = {"scale": grid.resolution, "min": [x0, y0, 0.0], "max": [x0 + w * grid.resolution, y0 + h * grid.resolution, top]}
    return bytes(png), meta


# ---------------------------------------------------------------- PLY layouts


def morton_order(means: np.ndarray) -> np.ndarray:
    """The order of a 30-bit Morton code over the points' bounds (splat-transform sorts so before chunking)."""
    lo, hi = means.min(axis=0), means.max(axis=0)
    q = np.clip(((means - lo) / np.maximum(hi - lo, 1e-9) * 1023).astype(np.uint64), 0, 1023)

    def spread(v: np.ndarray) -> np.ndarray:
        v = (v | (v << np.uint64(16))) & np.uint64(0x030000FF)
        v = (v | (v << np.uint64(8))) & np.uint64(0x0300F00F)
        v = (v | (v << np.uint64(4))) & np.uint64(0x030C30C3)
        return (v | (v << np.uint64(2))) & np.uint64(0x09249249)

    code = spread(q[:, 0]) | (spread(q[:, 1]) << np.uint64(1)) | (spread(q[:, 2]) << np.uint64(2))
    return np.argsort(code, kind="stable")


def _unorm(v: np.ndarray, bits: int) -> np.ndarray:
    t = (1 << bits) - 1
    return np.clip(np.floor(v * t + 0.5), 0, t).astype(np.uint32)


def _normalise(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    span = hi - lo
    t = np.where(span < 1e-5, 0.0, (x - lo) / np.where(span < 1e-5, 1.0, span))
    return np.where(x <= lo, 0.0, np.where(x >= hi, 1.0, t))


def compressed_ply(g: Gaussians) -> bytes:
    n = g.count
    chunks = math.ceil(n / CHUNK)
    pad = np.concatenate([np.arange(n), np.full(chunks * CHUNK - n, n - 1)])  # the last Gaussian fills the last chunk

    def chunked(a: np.ndarray) -> np.ndarray:
        return a[pad].astype(np.float64).reshape(chunks, CHUNK, *a.shape[1:])

    pos, scl = chunked(g.means), chunked(g.log_scales)
    rgb = chunked(g.sh[:, 0, :]) * SH_C0 + 0.5
    p_lo, p_hi = pos.min(axis=1, keepdims=True), pos.max(axis=1, keepdims=True)
    s_lo, s_hi = np.clip(scl.min(axis=1, keepdims=True), -20, 20), np.clip(scl.max(axis=1, keepdims=True), -20, 20)
    c_lo, c_hi = rgb.min(axis=1, keepdims=True), rgb.max(axis=1, keepdims=True)

    def pack111011(v: np.ndarray) -> np.ndarray:
        return (_unorm(v[..., 0], 11) << 21) | (_unorm(v[..., 1], 10) << 11) | _unorm(v[..., 2], 11)

    position = pack111011(_normalise(pos, p_lo, p_hi))
    scale = pack111011(_normalise(scl, s_lo, s_hi))
    c = _normalise(rgb, c_lo, c_hi)
    alpha = 1.0 / (1.0 + np.exp(-chunked(g.opacity_logits)))
    colour = (_unorm(c[..., 0], 8) << 24) | (_unorm(c[..., 1], 8) << 16) | (_unorm(c[..., 2], 8) << 8) | _unorm(alpha, 8)
    q = chunked(g.quats_wxyz)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    largest = np.abs(q).argmax(axis=-1)
    q = np.where(np.take_along_axis(q, largest[..., None], -1) < 0, -q, q)
    rotation = largest.astype(np.uint32)
    for k in range(4):
        others = q[..., k] * (math.sqrt(2) * 0.5) + 0.5
        keep = largest != k
        rotation = np.where(keep, (rotation << 10) | _unorm(others, 10), rotation)

    chunk_props = ["min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "min_scale_x", "min_scale_y", "min_scale_z",
                   "max_scale_x", "max_scale_y", "max_scale_z", "min_r", "min_g", "min_b", "max_r", "max_g", "max_b"]
    chunk = np.concatenate([p_lo, p_hi, s_lo, s_hi, c_lo, c_hi], axis=-1)[:, 0, :].astype("<f4")
    vertex = np.stack([position, rotation, scale, colour], axis=-1).reshape(-1, 4)[:n].astype("<u4")
    k = g.sh.shape[1]
    header = ["ply", "format binary_little_endian 1.0", "comment Generated by a sagebench test fixture",
              f"element chunk {chunks}", *[f"property float {p}" for p in chunk_props],
              f"element vertex {n}", *[f"property uint {p}" for p in ("packed_position", "packed_rotation",
                                                                        "packed_scale", "packed_color")]]
    body = chunk.tobytes() + vertex.tobytes()
    if k > 1:
        rest = g.sh[:, 1:, :].transpose(0, 2, 1).reshape(n, 3 * (k - 1)).astype(np.float64)  # channel-major
        header += [f"element sh {n}", *[f"property uchar f_rest_{i}" for i in range(3 * (k - 1))]]
        body += np.clip(np.trunc((rest / 8 + 0.5) * 256), 0, 255).astype(np.uint8).tobytes()
    return ("\n".join([*header, "end_header"]) + "\n").encode() + body


def inria_ply(g: Gaussians) -> bytes:
    """The INRIA layout without instance ids (x y z nx ny nz f_dc f_rest opacity scale rot)."""
    n, k = g.count, g.sh.shape[1]
    rest = g.sh[:, 1:, :].transpose(0, 2, 1).reshape(n, 3 * (k - 1))
    cols = [g.means, np.zeros((n, 3), np.float32), g.sh[:, 0, :], rest, g.opacity_logits[:, None], g.log_scales,
            g.quats_wxyz]
    names = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", *[f"f_rest_{i}" for i in range(rest.shape[1])],
             "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    header = ["ply", "format binary_little_endian 1.0", f"element vertex {n}", *[f"property float {p}" for p in names],
              "end_header"]
    return ("\n".join(header) + "\n").encode() + np.concatenate(cols, axis=1).astype("<f4").tobytes()


def collision_usd(scene: LoadedScene, path: Path, *, turned: bool = False) -> None:
    """A USD file with one Mesh prim per labelled object (not walls, floors, ceilings), as SAGE-3D ships them."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.Xform.Define(stage, "/collision")
    for obj in scene.spec.objects:
        if obj.kind in ("wall", "floor", "ceiling"):
            continue
        mesh = scene.meshes[obj.instance_id]
        v = mesh.vertices * ([-1, -1, 1] if turned else 1)
        prim = UsdGeom.Mesh.Define(stage, f"/collision/obj_{obj.instance_id}")
        prim.GetPointsAttr().Set(v.tolist())
        prim.GetFaceVertexCountsAttr().Set([3] * len(mesh.faces))
        prim.GetFaceVertexIndicesAttr().Set(mesh.faces.reshape(-1).tolist())
    stage.GetRootLayer().Save()


# ---------------------------------------------------------------- round-trip measures


def on_grid(values: np.ndarray, grid: Grid, target: Grid) -> np.ndarray:
    """`values` [H, W] on `grid` resampled onto `target` (same resolution, origins on its multiples); 0 outside."""
    out = np.zeros(target.shape, dtype=values.dtype)
    dr = round((target.origin[1] - grid.origin[1]) / grid.resolution)
    dc = round((target.origin[0] - grid.origin[0]) / grid.resolution)
    rows, cols = np.mgrid[0:target.shape[0], 0:target.shape[1]]
    r, c = rows + dr, cols + dc
    ok = (r >= 0) & (r < values.shape[0]) & (c >= 0) & (c < values.shape[1])
    out[ok] = values[r[ok], c[ok]]
    return out


def iou(a: np.ndarray, b: np.ndarray) -> float:
    union = int((a | b).sum())
    return float((a & b).sum()) / union if union else 1.0


def band_footprint_ious(truth: Truth, imported: LoadedScene, label_of: dict[int, int],
                        band: tuple[float, float] = (0.05, 1.2)) -> list[float]:
    """Per labelled object standing in the band in either scene: the IoU of the cells its geometry blocks in
    the band, mesh against import (label_of: imported instance id -> the mesh scene's)."""
    grid = truth.topdown.grid
    out = []
    for iid, tid in sorted(label_of.items()):
        a = band_occupancy(*mesh_parts(truth.scene.meshes[tid]), grid, *band)
        b = band_occupancy(*mesh_parts(imported.meshes[iid]), grid, *band)
        if a.any() or b.any():
            out.append(iou(a, b))
    return out


def in_box_share(truth: Truth, folder: Path, assigned: np.ndarray, label_of: dict[int, int],
                 margin: float = 0.02) -> float:
    """Of the Gaussians of labelled objects (not walls, floors, ceilings) that lie inside their own label's box
    (grown by `margin`), the share assigned that label's instance (`assigned` [N], in the PLY's order;
    label_of: imported instance id -> the mesh scene's)."""
    from sagebench.importers.boxes import box_from_corners
    from sagebench.splats.ply import read_ply

    labels = json.loads((folder / "labels.json").read_text())
    means = read_ply(next(folder / n for n in ("3dgs_compressed.ply", "3dgs.ply") if (folder / n).exists())).means
    to_mesh_id = np.zeros(max(assigned.max(), max(label_of, default=0)) + 1, dtype=np.int64)
    for iid, tid in label_of.items():
        to_mesh_id[iid] = tid
    got = to_mesh_id[assigned]
    right = total = 0
    for lab, tid in zip(labels, truth.label_ids):
        if lab["label"] in ("wall", "floor", "ceiling"):
            continue
        box = box_from_corners(np.array([[c["x"], c["y"], c["z"]] for c in lab["bounding_box"]]))
        mine = np.flatnonzero(truth.gaussian_ids == tid)
        held = mine[box.contains(means[mine], margin)]
        total += len(held)
        right += int((got[held] == tid).sum())
    return right / max(total, 1)


def empty_space_filled(truth_mesh: trimesh.Trimesh, mesh: trimesh.Trimesh, *, step: float = 0.02,
                       clearance: float = 0.03, band_min: float = 0.05) -> float | None:
    """The share of the empty space inside an object's tightest box (a desk's knee space, an L-sofa's inner
    corner; above `band_min`, at least `clearance` from the true surface and outside it) that `mesh`'s convex
    parts fill; None where the box holds no such space. Judged on a `step` grid; `mesh` is in the same frame."""
    from scipy.spatial import cKDTree

    from sagebench.importers.boxes import box_from_corners
    from sagebench.topdown.footprints import sample_surface

    box = box_from_corners(obb_corners(truth_mesh))
    axes = [np.arange(-h + step / 2, h, step) for h in box.half]
    local = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    points = box.centre + local @ box.axes
    points = points[points[:, 2] >= band_min]
    tris, _ = mesh_parts(truth_mesh)
    surface = sample_surface(tris, int(truth_mesh.area / 1e-4) + 1, np.random.default_rng(0))
    empty = (cKDTree(surface).query(points)[0] >= clearance) & ~_in_parts(truth_mesh, points)
    if not empty.any():
        return None
    return float(_in_parts(mesh, points[empty]).mean())


def _in_parts(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """[N] whether each point lies in one of the mesh's connected parts, each taken as its convex hull (as the
    colliders and the band footprint take them)."""
    from scipy.spatial import Delaunay

    tris, part = mesh_parts(mesh)
    inside = np.zeros(len(points), dtype=bool)
    for k in range(int(part.max()) + 1):
        verts = np.unique(tris[part == k].reshape(-1, 3), axis=0)
        if len(verts) >= 4 and np.linalg.matrix_rank(verts[1:] - verts[0]) == 3:
            inside |= Delaunay(verts).find_simplex(points) >= 0
    return inside


# ---------------------------------------------------------------- messy data


@dataclass(frozen=True)
class Mess:
    """What `write_messy_folder` did: the instance id (mesh scene) of the removed label, the floaters added and the
    labels.json index of the label given the ins_id before it, with that ins_id (None when none was)."""

    removed: int
    floaters: int
    duplicated: tuple[int, str] | None


def write_messy_folder(clean: Path, out: Path, truth: Truth, *, removed: str = "bed", floaters: float = 0.05,
                       jitter: float = 0.01, duplicate: bool = True, seed: int = 0) -> Mess:
    """A copy of the InteriorGS folder `clean` as real captures come: every Gaussian moved by `jitter` (m, normal
    per axis), a `floaters` share more Gaussians scattered over the scene's bounds (small, of any opacity: the
    stray splats training leaves in the air), the first label of category `removed` taken out of labels.json and,
    with `duplicate`, the last label given the ins_id of the one before it. Written in the INRIA layout (3dgs.ply)."""
    from sagebench.splats.ply import read_ply

    rng = np.random.default_rng(seed)
    out.mkdir(parents=True, exist_ok=True)
    for name in ("structure.json", "occupancy.png", "occupancy.json"):
        (out / name).write_bytes((clean / name).read_bytes())
    g = read_ply(next(clean / n for n in ("3dgs_compressed.ply", "3dgs.ply") if (clean / n).exists()))
    meta = json.loads((clean / "occupancy.json").read_text())
    n = int(round(g.count * floaters))
    means = np.concatenate([g.means + rng.normal(0, jitter, g.means.shape),
                            rng.uniform(meta["min"], meta["max"], (n, 3))]).astype(np.float32)
    quats = rng.normal(size=(n, 4))
    f32 = np.float32
    stray = Gaussians(means, np.concatenate([g.quats_wxyz, quats / np.linalg.norm(quats, axis=1, keepdims=True)]).astype(f32),
                      np.concatenate([g.log_scales, np.log(rng.uniform(0.005, 0.03, (n, 3)))]).astype(f32),
                      np.concatenate([g.opacity_logits, rng.uniform(-3.0, 3.0, n)]).astype(f32),
                      np.concatenate([g.sh, np.repeat(g.sh[:1] * 0, n, axis=0)]), np.zeros(g.count + n, np.int32))
    (out / "3dgs.ply").write_bytes(inria_ply(stray))
    labels = json.loads((clean / "labels.json").read_text())
    k = next(i for i, lab in enumerate(labels) if lab["label"] == removed.replace("_", " "))
    labels = labels[:k] + labels[k + 1:]
    if duplicate:
        labels[-1]["ins_id"] = labels[-2]["ins_id"]
    (out / "labels.json").write_text(json.dumps(labels, indent=1))
    return Mess(truth.label_ids[k], n, (len(labels) - 1, labels[-1]["ins_id"]) if duplicate else None)


def volume_iou(truth_mesh: trimesh.Trimesh, mesh: trimesh.Trimesh, *, step: float = 0.02) -> float:
    """The IoU of the volume inside the mesh scene's object (each closed piece as it is, concave or not) and that
    inside the imported one's connected parts (each taken as its convex hull, as the colliders take them), judged
    on a `step` grid over both meshes' bounds (set off by an odd fraction of a step, so that no row of it lies on
    a voxel face both meshes end a hair short of)."""
    lo = np.minimum(truth_mesh.bounds[0], mesh.bounds[0])
    hi = np.maximum(truth_mesh.bounds[1], mesh.bounds[1])
    axes = [np.arange(a + step * 0.37, b, step) for a, b in zip(lo, hi)]
    points = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    a = np.zeros(len(points), dtype=bool)
    for piece in truth_mesh.split(only_watertight=False):
        a |= piece.contains(points) if piece.is_watertight else _in_parts(piece, points)
    b = _in_parts(mesh, points)
    return float((a & b).sum()) / max(int((a | b).sum()), 1)
