"""gsplat 1.5.3's `rasterization` (pinhole, classic, "RGB+ED") in plain numpy, for tests on machines without CUDA.

Written from gsplat's own description of its math: `gsplat/cuda/_torch_impl.py` (quaternion to rotation, world to
camera, perspective projection with its asymmetric x/z clamp, the eps2d blur, conics, the SH basis in Sloan's
form) and the CUDA kernels it stands beside (`ProjectionEWA3DGSFused.cu`: opacity-aware 3.33-sigma box, cull
below 1/255; `IntersectTile.cu`: tile ranges; `RasterizeToPixels3DGSFwd.cu`: pixel centres at +0.5, alpha capped
at 0.999, skipped below 1/255 or for negative sigma, stop when the next transmittance would be <= 1e-4). Slow and
small: a test feeds it what sagebench's conversion produces and compares with the CPU renderer.
"""

from __future__ import annotations

import numpy as np

ALPHA_THRESHOLD = 1.0 / 255.0


def quat_to_rotmat(q: np.ndarray) -> np.ndarray:
    """[N, 4] wxyz (normalised here) -> [N, 3, 3]."""
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q.T
    return np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
                     2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                     2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1).reshape(-1, 3, 3)


def sh_basis(k: int, d: np.ndarray) -> np.ndarray:
    """[N, K] SH basis at unit directions [N, 3], Sloan's evaluation as gsplat writes it."""
    out = np.zeros((len(d), k))
    out[:, 0] = 0.2820947917738781
    if k <= 1:
        return out
    x, y, z = d.T
    a = -0.48860251190292
    out[:, 1], out[:, 2], out[:, 3] = a * y, -a * z, a * x
    if k <= 4:
        return out
    z2, c1, s1 = z * z, x * x - y * y, 2 * x * y
    b = -1.092548430592079 * z
    out[:, 4], out[:, 5], out[:, 6] = 0.5462742152960395 * s1, b * y, 0.9461746957575601 * z2 - 0.3153915652525201
    out[:, 7], out[:, 8] = b * x, 0.5462742152960395 * c1
    if k <= 9:
        return out
    c = -2.285228997322329 * z2 + 0.4570457994644658
    b = 1.445305721320277 * z
    a = -0.5900435899266435
    c2, s2 = x * c1 - y * s1, x * s1 + y * c1
    out[:, 9], out[:, 10], out[:, 11] = a * s2, b * s1, c * y
    out[:, 12], out[:, 13], out[:, 14], out[:, 15] = z * (1.865881662950577 * z2 - 1.119528997770346), c * x, b * c1, a * c2
    return out


def project(means, quats, scales, opacities, viewmat, K, width, height, *, near_plane, eps2d, far_plane=1e10):
    """One camera: means2d [N, 2], conics [N, 3], depths [N], radii [N, 2] int (0 = culled)."""
    R = quat_to_rotmat(quats.astype(np.float64))
    M = R * scales.astype(np.float64)[:, None, :]
    cov = M @ M.transpose(0, 2, 1)
    Rv, tv = viewmat[:3, :3].astype(np.float64), viewmat[:3, 3].astype(np.float64)
    p = means.astype(np.float64) @ Rv.T + tv
    cov_c = Rv @ cov @ Rv.T
    fx, fy, cx, cy = (float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]))
    tz = np.where(p[:, 2] > 0, p[:, 2], 1.0)
    tan_x, tan_y = 0.5 * width / fx, 0.5 * height / fy
    tx = tz * np.clip(p[:, 0] / tz, -(cx / fx + 0.3 * tan_x), (width - cx) / fx + 0.3 * tan_x)
    ty = tz * np.clip(p[:, 1] / tz, -(cy / fy + 0.3 * tan_y), (height - cy) / fy + 0.3 * tan_y)
    J = np.zeros((len(p), 2, 3))
    J[:, 0, 0], J[:, 0, 2] = fx / tz, -fx * tx / tz**2
    J[:, 1, 1], J[:, 1, 2] = fy / tz, -fy * ty / tz**2
    cov2 = J @ cov_c @ J.transpose(0, 2, 1) + eps2d * np.eye(2)
    det = cov2[:, 0, 0] * cov2[:, 1, 1] - cov2[:, 0, 1] * cov2[:, 1, 0]
    dets = np.where(det > 0, det, 1.0)
    conics = np.stack([cov2[:, 1, 1] / dets, -cov2[:, 0, 1] / dets, cov2[:, 0, 0] / dets], -1)
    means2d = np.stack([fx * p[:, 0] / tz + cx, fy * p[:, 1] / tz + cy], -1)
    o = opacities.astype(np.float64)
    extend = np.minimum(3.33, np.sqrt(2.0 * np.log(np.maximum(o, ALPHA_THRESHOLD) / ALPHA_THRESHOLD)))
    radii = np.stack([np.ceil(extend * np.sqrt(cov2[:, 0, 0])), np.ceil(extend * np.sqrt(cov2[:, 1, 1]))], -1)
    keep = (p[:, 2] >= near_plane) & (p[:, 2] <= far_plane) & (det > 0) & (o >= ALPHA_THRESHOLD)
    keep &= (means2d[:, 0] + radii[:, 0] > 0) & (means2d[:, 0] - radii[:, 0] < width)
    keep &= (means2d[:, 1] + radii[:, 1] > 0) & (means2d[:, 1] - radii[:, 1] < height)
    keep &= (radii > 0).any(axis=1)
    radii[~keep] = 0
    return means2d, conics, p[:, 2], radii.astype(np.int64)


def rasterization(means, quats, scales, opacities, colors, viewmats, Ks, width, height, *, sh_degree, backgrounds,
                  near_plane, eps2d, render_mode, rasterize_mode, tile_size, packed=False):
    """gsplat.rasterization for these arguments: colors [C, H, W, 4] (RGB + expected depth), alphas
    [C, H, W, 1], meta {}."""
    assert render_mode == "RGB+ED" and rasterize_mode == "classic", (render_mode, rasterize_mode)
    means, quats, scales, opacities, colors = (np.asarray(a) for a in (means, quats, scales, opacities, colors))
    viewmats, Ks, backgrounds = np.asarray(viewmats), np.asarray(Ks), np.asarray(backgrounds)
    k = (sh_degree + 1) ** 2
    assert colors.ndim == 3 and colors.shape[1] >= k, colors.shape
    out_c = np.zeros((len(viewmats), height, width, 4), np.float32)
    out_a = np.zeros((len(viewmats), height, width, 1), np.float32)
    for c, (vm, K) in enumerate(zip(viewmats, Ks)):
        m2, conic, depth, radii = project(means, quats, scales, opacities, vm, K, width, height,
                                          near_plane=near_plane, eps2d=eps2d)
        campos = np.linalg.inv(vm.astype(np.float64))[:3, 3]
        dirs = means.astype(np.float64) - campos
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        rgb = np.maximum(np.einsum("nk,nkc->nc", sh_basis(k, dirs), colors[:, :k].astype(np.float64)) + 0.5, 0.0)
        feats = np.concatenate([rgb, depth[:, None]], axis=1)
        tmin = np.floor((m2 - radii) / tile_size).astype(np.int64)
        tmax = np.ceil((m2 + radii) / tile_size).astype(np.int64)
        visible = np.flatnonzero((radii > 0).all(axis=1))
        order = visible[np.argsort(depth[visible], kind="stable")]
        bg = np.concatenate([backgrounds[c].astype(np.float64), [0.0]])
        for i in range(height):
            for j in range(width):
                tx, ty = j // tile_size, i // tile_size
                acc, t = np.zeros(4), 1.0
                for g in order:
                    if not (tmin[g, 0] <= tx < tmax[g, 0] and tmin[g, 1] <= ty < tmax[g, 1]):
                        continue
                    dx, dy = m2[g, 0] - (j + 0.5), m2[g, 1] - (i + 0.5)
                    sigma = 0.5 * (conic[g, 0] * dx * dx + conic[g, 2] * dy * dy) + conic[g, 1] * dx * dy
                    alpha = min(0.999, float(opacities[g]) * np.exp(-sigma))
                    if sigma < 0 or alpha < ALPHA_THRESHOLD:
                        continue
                    nxt = t * (1.0 - alpha)
                    if nxt <= 1e-4:
                        break
                    acc += alpha * t * feats[g]
                    t = nxt
                a = 1.0 - t
                out_c[c, i, j] = acc + t * bg
                out_c[c, i, j, 3] = acc[3] / max(a, 1e-10)
                out_a[c, i, j, 0] = a
    return out_c, out_a, {}
