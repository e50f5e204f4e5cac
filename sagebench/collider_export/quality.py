"""How well a set of convex parts stands in for the mesh it was made from, measured, in centimetres.

Four figures, each one-sided so that over- and under-coverage are told apart:
- `to_source`: sampled points of the collider surface (faces between touching parts left out) to the
  source surface: where the collider bulges past the source (a hull bridging a notch);
- `from_source`: sampled points of the source surface to the collider *solid* (0 inside a part): where
  the source pokes out of the collider (what an agent could walk into unseen);
- `outside_volume`: collider volume outside the source's closed envelope (the source voxelised at
  `volume_pitch`, cavities filled; holes smaller than a voxel are sealed by it);
- `band_over` / `band_under`: the agent-height band footprints (the xy shadow of what lies between the
  band's bottom and top, enclosed areas filled, rasterised at `band_pitch`): the farthest collider cell
  from the source's footprint, and the farthest source cell from the collider's. These decide navigation.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numba
import numpy as np
import trimesh
from scipy import ndimage

from sagebench.collider_export.convex import ConvexPart
from sagebench.collider_export.fanout import map_processes


@dataclass(frozen=True)
class QualitySettings:
    """How densely the measure samples; finer is slower and closer to the exact figures."""

    samples: int = 1500  # surface points per side
    band_pitch: float = 0.01  # m, footprint raster cell
    volume_pitch: float = 0.02  # m, envelope voxel
    seed: int = 0


@dataclass(frozen=True)
class ColliderQuality:
    """One collider against its source; distances in cm, volume in litres."""

    to_source_max_cm: float
    to_source_mean_cm: float
    from_source_max_cm: float
    from_source_mean_cm: float
    outside_volume_l: float
    band_over_cm: float
    band_under_cm: float

    @property
    def band_error_cm(self) -> float:
        """The worse of the two band figures: how far navigation could be wrong about this object."""
        return max(self.band_over_cm, self.band_under_cm)

    def as_dict(self) -> dict[str, float]:
        return {k: round(float(getattr(self, k)), 3) for k in self.__dataclass_fields__}


def measure(
    vertices: np.ndarray,
    faces: np.ndarray,
    parts: Sequence[ConvexPart],
    *,
    band: tuple[float, float],
    settings: QualitySettings = QualitySettings(),
) -> ColliderQuality:
    """The quality of `parts` as a collider for the mesh (vertices [V, 3] m, faces [F, 3]); `band` is the agent
    band (bottom, top) as z in the mesh's frame."""
    source = trimesh.Trimesh(np.asarray(vertices, dtype=np.float64), np.asarray(faces, dtype=np.int64), process=False)
    collider = trimesh.util.concatenate([trimesh.Trimesh(p.vertices, p.faces, process=False) for p in parts])
    rng = np.random.default_rng(settings.seed)
    planes = [part_planes(p) for p in parts]

    coll_pts, coll_face = sample_surface(collider.vertices, collider.faces, settings.samples, rng)
    owner = _face_owner(parts)[coll_face]
    keep = ~_inside_other(coll_pts + 1e-6 * collider.face_normals[coll_face], owner, planes)
    to_source = _distances(source, coll_pts[keep])
    src_pts, _ = sample_surface(source.vertices, source.faces, settings.samples, rng)
    inside = np.zeros(len(src_pts), dtype=bool)
    for pl in planes:
        inside |= _inside(src_pts, pl, eps=1e-7)
    from_source = np.zeros(len(src_pts))
    if (~inside).any():
        from_source[~inside] = _distances(collider, src_pts[~inside])
    over, under = band_errors(source, parts, band, settings.band_pitch)
    return ColliderQuality(
        to_source_max_cm=_cm(to_source.max(initial=0.0)), to_source_mean_cm=_cm(to_source.mean() if len(to_source) else 0.0),
        from_source_max_cm=_cm(from_source.max(initial=0.0)), from_source_mean_cm=_cm(from_source.mean()),
        outside_volume_l=outside_volume(source, parts, planes, settings.volume_pitch) * 1000.0,
        band_over_cm=_cm(over), band_under_cm=_cm(under),
    )


def _cm(metres: float) -> float:
    return float(metres) * 100.0


def part_planes(part: ConvexPart) -> np.ndarray:
    """Outward face planes [F, 4] (unit normal n, offset d: n.x <= d inside) of a convex part."""
    v, f = part.vertices, part.faces
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    length = np.linalg.norm(n, axis=1)
    ok = length > 1e-15
    n = n[ok] / length[ok, None]
    return np.column_stack([n, np.einsum("ij,ij->i", n, v[f[ok, 0]])])


def _inside(points: np.ndarray, planes: np.ndarray, eps: float = 1e-9) -> np.ndarray:
    """[N] bool: inside the convex part (planes [F, 4]) or on its boundary (within eps of it). Each point stops at
    the first plane it is outside of, so a part of thousands of faces costs little for points far from it."""
    out = np.empty(len(points), dtype=bool)
    _inside_kernel(np.ascontiguousarray(points, dtype=np.float64), np.ascontiguousarray(planes, dtype=np.float64),
                   float(eps), out)
    return out


@numba.njit(cache=True)
def _inside_kernel(points: np.ndarray, planes: np.ndarray, eps: float, out: np.ndarray) -> None:
    for i in range(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        out[i] = True
        for j in range(planes.shape[0]):
            if not (planes[j, 0] * x + planes[j, 1] * y + planes[j, 2] * z - planes[j, 3] <= eps):
                out[i] = False
                break


def inside_reference(points: np.ndarray, planes: np.ndarray, eps: float = 1e-9) -> np.ndarray:
    """`_inside` the plain way: every point against every plane [N, F]."""
    return np.all(points @ planes[:, :3].T - planes[:, 3] <= eps, axis=1)


def _inside_other(points: np.ndarray, owner: np.ndarray, planes: list[np.ndarray]) -> np.ndarray:
    """[N] bool: each point (just outside part owner[i]'s surface) lies in some other part: a face between
    touching or overlapping parts, not collider surface."""
    out = np.zeros(len(points), dtype=bool)
    for k, pl in enumerate(planes):
        other = owner != k
        out[other] |= _inside(points[other], pl)
    return out


def _face_owner(parts: Sequence[ConvexPart]) -> np.ndarray:
    """[F] the part each face of the concatenated collider belongs to."""
    return np.repeat(np.arange(len(parts)), [len(p.faces) for p in parts])


def sample_surface(vertices: np.ndarray, faces: np.ndarray, n: int,
                   rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """n points [n, 3] spread over the triangles by area, and the face [n] each came from."""
    tri = np.asarray(vertices)[np.asarray(faces)]
    area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if area.sum() <= 0:
        return tri[:, 0][:1].copy(), np.zeros(1, dtype=np.int64)
    face = rng.choice(len(tri), size=n, p=area / area.sum())
    u, w = rng.random(n), rng.random(n)
    flip = u + w > 1
    u[flip], w[flip] = 1 - u[flip], 1 - w[flip]
    t = tri[face]
    pts = t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + w[:, None] * (t[:, 2] - t[:, 0])
    return pts, face


def _distances(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """Exact distance [N] from each point to the mesh's surface: the nearest of the triangle corners and centres
    bounds it, and only the triangles whose boxes come within that bound are measured (an R-tree bulk-loaded
    from arrays; trimesh.proximity.closest_point does the same search from corners alone, on a tree it builds
    point by point in Python)."""
    import rtree
    from scipy.spatial import cKDTree

    points = np.asarray(points, dtype=np.float64)
    if len(points) == 0:
        return np.zeros(0)
    tri = np.asarray(mesh.vertices, dtype=np.float64)[np.asarray(mesh.faces)]  # [T, 3, 3]
    tree = rtree.index.Index((np.arange(len(tri), dtype=np.int64), tri.min(axis=1), tri.max(axis=1)),
                             properties=rtree.index.Property(dimension=3))
    bound = cKDTree(np.concatenate([tri.reshape(-1, 3), tri.mean(axis=1)])).query(points)[0][:, None] + 1e-9
    ids, counts = tree.intersection_v(points - bound, points + bound)
    counts = counts.astype(np.int64)
    owner = np.repeat(np.arange(len(points)), counts)
    gap = points[owner] - trimesh.triangles.closest_point(tri[ids], points[owner])
    start = np.concatenate([[0], np.cumsum(counts)[:-1]])
    return np.sqrt(np.minimum.reduceat(np.einsum("ij,ij->i", gap, gap), start))


def outside_volume(source: trimesh.Trimesh, parts: Sequence[ConvexPart], planes: list[np.ndarray],
                   pitch: float) -> float:
    """m^3 of the parts outside the source's envelope, counted on the cell centres of a `pitch` grid."""
    all_v = np.concatenate([source.vertices, *[p.vertices for p in parts]])
    lo = all_v.min(axis=0) - pitch
    shape = np.ceil((all_v.max(axis=0) + pitch - lo) / pitch).astype(int) + 1
    envelope = np.zeros(shape, dtype=bool)
    idx = np.floor((lattice_points(source.vertices[source.faces], pitch / 2) - lo) / pitch).astype(int)
    envelope[idx[:, 0], idx[:, 1], idx[:, 2]] = True
    envelope = ndimage.binary_fill_holes(envelope)
    outside = 0
    for part, pl in zip(parts, planes):
        i0 = np.floor((part.vertices.min(axis=0) - lo) / pitch).astype(int)
        i1 = np.ceil((part.vertices.max(axis=0) - lo) / pitch).astype(int) + 1
        block = (slice(i0[0], i1[0]), slice(i0[1], i1[1]), slice(i0[2], i1[2]))
        free = np.argwhere(~envelope[block])  # only cells not yet counted need the half-space test
        fresh = free[_inside(lo + (free + i0 + 0.5) * pitch, pl, eps=0.0)] + i0
        outside += len(fresh)
        envelope[fresh[:, 0], fresh[:, 1], fresh[:, 2]] = True  # a cell two parts share counts once
    return float(outside) * pitch**3


def lattice_points(triangles: np.ndarray, spacing: float) -> np.ndarray:
    """Points [N, 3] on a barycentric lattice over each triangle [T, 3, 3], no two neighbours farther apart than
    `spacing`: every cell of a grid of pitch 2 * spacing that a triangle crosses gets one of its points."""
    return lattice_rows(triangles, spacing)[0]


def lattice_rows(triangles: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """lattice_points, and the row [N] each point lies on: the points of one row are collinear and consecutive,
    in order along it (a triangle's corners are rows of one point each)."""
    tri = np.asarray(triangles, dtype=np.float64)
    edge = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
    steps = np.maximum(np.ceil(edge / spacing).astype(int), 1)
    out = [tri.reshape(-1, 3)]
    rows = [np.arange(3 * len(tri))]
    for n in np.unique(steps):
        t = tri[steps == n]
        i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
        keep = i + j <= n
        u, w = i[keep] / n, j[keep] / n  # [K] barycentric weights of vertices 1 and 2, i-major
        pts = t[:, None, 0] + u[None, :, None] * (t[:, None, 1] - t[:, None, 0]) + w[None, :, None] * (t[:, None, 2] - t[:, None, 0])
        out.append(pts.reshape(-1, 3))
        first = rows[-1][-1] + 1 if len(rows[-1]) else 0
        rows.append(first + (np.arange(len(t))[:, None] * (n + 1) + i[keep][None, :]).ravel())
    return np.concatenate(out), np.concatenate(rows)


def band_errors(source: trimesh.Trimesh, parts: Sequence[ConvexPart], band: tuple[float, float],
                pitch: float) -> tuple[float, float]:
    """(farthest collider footprint cell from the source footprint, farthest source cell from the collider
    footprint), m, both footprints the band's xy shadow rasterised the same way with enclosed areas filled;
    0 where both are empty, inf where only one is."""
    z0, z1 = band
    src_polys = band_polygons(source.vertices[source.faces], z0, z1)
    part_polys = [q for p in parts for q in band_polygons(p.vertices[p.faces], z0, z1)]
    if not len(src_polys) and not len(part_polys):
        return 0.0, 0.0
    if not len(src_polys) or not len(part_polys):
        return float("inf"), float("inf")
    pts = np.concatenate([np.concatenate(src_polys), np.concatenate(part_polys)])
    lo = pts.min(axis=0) - 2 * pitch
    shape = tuple(np.ceil((pts.max(axis=0) + 2 * pitch - lo) / pitch).astype(int)[::-1] + 1)  # [rows=y, cols=x]
    src = ndimage.binary_fill_holes(rasterise(src_polys, lo, pitch, shape))
    col = ndimage.binary_fill_holes(rasterise(part_polys, lo, pitch, shape))
    over = ndimage.distance_transform_edt(~src, sampling=pitch)[col].max(initial=0.0)
    under = ndimage.distance_transform_edt(~col, sampling=pitch)[src].max(initial=0.0)
    return float(over), float(under)


class BandReach:
    """How far a convex part's agent-band footprint lies past a mesh's (m): band_errors' `over` figure for one
    part, with the mesh's footprint rasterised once, so that merging can judge many candidate hulls cheaply
    (a convex part's band footprint is the 2-D hull of its surface's, one polygon). `extent` [N, 3]: points
    whose xy bounds hold every part to be judged."""

    def __init__(self, source: trimesh.Trimesh, extent: np.ndarray, band: tuple[float, float], pitch: float = 0.01):
        self.band, self.pitch = band, pitch
        src_polys = band_polygons(source.vertices[source.faces], *band)
        xy = np.concatenate([np.asarray(extent, dtype=np.float64)[:, :2], *src_polys])
        self.lo = xy.min(axis=0) - 2 * pitch
        self.shape = tuple(np.ceil((xy.max(axis=0) + 2 * pitch - self.lo) / pitch).astype(int)[::-1] + 1)
        src = ndimage.binary_fill_holes(rasterise(src_polys, self.lo, pitch, self.shape))
        self.outside = ndimage.distance_transform_edt(~src, sampling=pitch) if src.any() else np.full(self.shape, np.inf)

    def __call__(self, part: ConvexPart) -> float:
        import cv2

        polys = band_polygons(part.vertices[part.faces], *self.band)
        if not polys:
            return 0.0
        outline = cv2.convexHull(np.concatenate(polys).astype(np.float32))[:, 0].astype(np.float64)
        return float(self.outside[rasterise([outline], self.lo, self.pitch, self.shape)].max(initial=0.0))


def band_polygons(triangles: np.ndarray, z0: float, z1: float) -> list[np.ndarray]:
    """The xy shadow of each triangle [T, 3, 3] clipped to z0 <= z <= z1: convex polygons [k, 2] (k <= 9, points in
    angular order, a segment or point where the clipped piece is vertical)."""
    tri = np.asarray(triangles, dtype=np.float64)
    zmin, zmax = tri[:, :, 2].min(axis=1), tri[:, :, 2].max(axis=1)
    tri = tri[(zmax >= z0) & (zmin <= z1)]
    if not len(tri):
        return []
    cands = [tri]  # vertices, kept where inside the band
    valid = [(tri[:, :, 2] >= z0) & (tri[:, :, 2] <= z1)]
    a, b = tri, np.roll(tri, -1, axis=1)
    for z in (z0, z1):
        dz = b[:, :, 2] - a[:, :, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (z - a[:, :, 2]) / dz
        ok = (dz != 0) & (t >= 0) & (t <= 1)
        cands.append(a + np.where(ok, t, 0.0)[:, :, None] * (b - a))
        valid.append(ok)
    pts = np.concatenate(cands, axis=1)[:, :, :2]  # [T, 9, 2]
    ok = np.concatenate(valid, axis=1)  # [T, 9]
    keep = ok.any(axis=1)
    pts, ok = pts[keep], ok[keep]
    centre = (pts * ok[:, :, None]).sum(axis=1) / ok.sum(axis=1)[:, None]
    angle = np.arctan2(pts[:, :, 1] - centre[:, None, 1], pts[:, :, 0] - centre[:, None, 0])
    order = np.argsort(np.where(ok, angle, np.inf), axis=1)
    pts = np.take_along_axis(pts, order[:, :, None], axis=1)
    counts = ok.sum(axis=1)
    return [p[:c] for p, c in zip(pts, counts)]


def rasterise(polygons: list[np.ndarray], lo: np.ndarray, pitch: float, shape: tuple[int, int]) -> np.ndarray:
    """[rows, cols] bool: the cells each convex polygon (xy, m) covers, drawn one by one (overlaps add up)."""
    import cv2

    shift = 8
    image = np.zeros(shape, dtype=np.uint8)
    if not len(polygons):
        return image.astype(bool)
    scale = float(1 << shift) / pitch
    ends = np.cumsum([len(p) for p in polygons])
    px = np.round((np.concatenate(polygons) - lo) * scale - (1 << shift) / 2).astype(np.int32)  # all at once
    for poly in np.split(px, ends[:-1]):
        cv2.fillConvexPoly(image, poly, 1, lineType=cv2.LINE_8, shift=shift)
    return image.astype(bool)


def band_in_mesh_frame(matrix: np.ndarray, band: tuple[float, float]) -> tuple[float, float] | None:
    """The agent's band (world z, m) as z in the mesh's own frame when `matrix` (4x4, mesh -> world) keeps z axes
    parallel (yaw, translation, uniform-in-z scale 1); None otherwise."""
    m = np.asarray(matrix, dtype=np.float64)
    if not (np.allclose(m[2, :3], [0.0, 0.0, 1.0], atol=1e-9) and np.allclose(m[:2, 2], 0.0, atol=1e-9)):
        return None
    return band[0] - m[2, 3], band[1] - m[2, 3]


def measure_placed(vertices: np.ndarray, faces: np.ndarray, parts: Sequence[ConvexPart], matrix: np.ndarray,
                   band: tuple[float, float], settings: QualitySettings = QualitySettings()) -> ColliderQuality:
    """`measure` for a mesh placed by `matrix` (4x4, mesh -> world) in a scene whose agent band is `band`
    (world z: floor + the agent's clearance .. floor + its height)."""
    local = band_in_mesh_frame(matrix, band)
    if local is not None:
        return measure(vertices, faces, parts, band=local, settings=settings)
    world = [ConvexPart(trimesh.transform_points(p.vertices, matrix), p.faces) for p in parts]
    return measure(trimesh.transform_points(vertices, matrix), faces, world, band=band, settings=settings)


def measure_objects(
    placed: Sequence[tuple[int, str, np.ndarray]],
    meshes: Mapping[str, tuple[np.ndarray, np.ndarray]],
    parts: Mapping[str, Sequence[ConvexPart]],
    band: tuple[float, float],
    settings: QualitySettings = QualitySettings(),
    *,
    workers: int = 1,
) -> dict[int, ColliderQuality]:
    """Quality per (instance id, mesh name, 4x4 mesh -> world matrix); one measurement per mesh and band height,
    so an asset placed many times on the floor costs one; measurements spread over up to `workers` processes."""
    keys = []
    first: dict[tuple, tuple[str, np.ndarray]] = {}
    for instance_id, name, matrix in placed:
        local = band_in_mesh_frame(matrix, band)
        key = (name, tuple(np.round(local, 9))) if local is not None else (name, instance_id)
        keys.append(key)
        first.setdefault(key, (name, matrix))
    jobs = [(*meshes[name], parts[name], matrix, band, settings) for name, matrix in first.values()]
    results = map_processes(measure_placed, jobs, workers=workers, sizes=[len(job[1]) for job in jobs])
    done = dict(zip(first, results))
    return {instance_id: done[key] for (instance_id, _, _), key in zip(placed, keys)}
