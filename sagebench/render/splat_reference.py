"""The plain reference splat renderer: numpy, float64, one pixel at a time over every Gaussian.

Slow on purpose; it spells out the conventions the fast tile renderer (splat_render) must reproduce:
quaternion wxyz, covariance R S S^T R^T, EWA projection with the reference rasterisers' clamp of x/z and
y/z to 1.3 tan(fov/2), +0.3 px on the 2D covariance diagonal, support cut at the 3-sigma ellipse,
opacity below 1/255 culled, alpha = min(0.99, opacity exp(-d^2/2)) and skipped below 1/255,
front-to-back by camera depth, stopping before transmittance would drop below 1e-4, colour
max(SH + 0.5, 0), Gaussians nearer than 0.01 m culled.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sagebench.render.camera import Camera
from sagebench.render.gaussians import Gaussians
from sagebench.render.sh import sh_to_rgb

NEAR = 0.01  # m
MIN_ALPHA = 1.0 / 255.0
MAX_ALPHA = 0.99
MIN_TRANSMITTANCE = 1e-4
DILATION = 0.3  # px^2 added to the 2D covariance diagonal
CUTOFF = 4.5  # half the squared Mahalanobis radius of the 3-sigma ellipse
FOV_CLAMP = 1.3


@dataclass(frozen=True)
class Frame:
    """One rendered view.

    rgb       [H, W, 3] float32  colour (not clipped to 1), background blended in
    depth     [H, W] float32     expected camera-z depth of the blended Gaussians, m; 0 where alpha is 0
    alpha     [H, W] float32     1 - final transmittance
    instance  [H, W] int32       instance id of the Gaussian with the largest blending weight; 0 where none
                                 (None from a backend that draws no instance ids: gsplat)
    """

    rgb: np.ndarray
    depth: np.ndarray
    alpha: np.ndarray
    instance: np.ndarray | None


@dataclass(frozen=True)
class Projected:
    """Screen-space Gaussians; `visible` [N] bool marks those that survive culling."""

    xy: np.ndarray  # [N, 2] image coordinates of the centre, px
    conic: np.ndarray  # [N, 3] inverse 2D covariance (a, b, c) of [[a, b], [b, c]], 1/px^2
    depth: np.ndarray  # [N] camera z, m
    rgb: np.ndarray  # [N, 3]
    opacity: np.ndarray  # [N]
    visible: np.ndarray  # [N] bool


def quat_to_rotmat(quats_wxyz: np.ndarray) -> np.ndarray:
    """[N, 4] quaternions (normalised here) -> [N, 3, 3] rotation matrices."""
    q = quats_wxyz.astype(np.float64)
    w, x, y, z = (q / np.linalg.norm(q, axis=1, keepdims=True)).T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=1)


def covariance_3d(quats_wxyz: np.ndarray, log_scales: np.ndarray) -> np.ndarray:
    """[N, 3, 3] world covariance R S S^T R^T."""
    m = quat_to_rotmat(quats_wxyz) * np.exp(log_scales.astype(np.float64))[:, None, :]
    return m @ m.transpose(0, 2, 1)


def project(g: Gaussians, cam: Camera) -> Projected:
    """EWA-project every Gaussian into `cam` (float64, vectorised over Gaussians)."""
    rot, t = cam.world_to_camera[:3, :3], cam.world_to_camera[:3, 3]
    p = g.means.astype(np.float64) @ rot.T + t
    z = p[:, 2]
    in_front = z > NEAR
    zs = np.where(in_front, z, 1.0)
    limx, limy = FOV_CLAMP * cam.width / (2 * cam.fx), FOV_CLAMP * cam.height / (2 * cam.fy)
    tx = np.clip(p[:, 0] / zs, -limx, limx) * zs
    ty = np.clip(p[:, 1] / zs, -limy, limy) * zs
    jac = np.zeros((g.count, 2, 3))
    jac[:, 0, 0] = cam.fx / zs
    jac[:, 0, 2] = -cam.fx * tx / zs**2
    jac[:, 1, 1] = cam.fy / zs
    jac[:, 1, 2] = -cam.fy * ty / zs**2
    tm = jac @ rot
    cov = tm @ covariance_3d(g.quats_wxyz, g.log_scales) @ tm.transpose(0, 2, 1)
    a, b, c = cov[:, 0, 0] + DILATION, cov[:, 0, 1], cov[:, 1, 1] + DILATION
    det = a * c - b * b
    ok = in_front & (det > 0)
    dets = np.where(ok, det, 1.0)
    opacity = 1.0 / (1.0 + np.exp(-g.opacity_logits.astype(np.float64)))
    dirs = g.means.astype(np.float64) - cam.position
    dirs /= np.maximum(np.linalg.norm(dirs, axis=1, keepdims=True), 1e-12)
    return Projected(
        xy=np.stack([cam.fx * p[:, 0] / zs + cam.cx, cam.fy * p[:, 1] / zs + cam.cy], axis=1),
        conic=np.stack([c / dets, -b / dets, a / dets], axis=1),
        depth=z,
        rgb=sh_to_rgb(g.sh, dirs),
        opacity=opacity,
        visible=ok & (opacity >= MIN_ALPHA),
    )


def render_reference(g: Gaussians, cam: Camera, *, background: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> Frame:
    """Render `g` through `cam`, compositing every visible Gaussian at every pixel centre."""
    pr = project(g, cam)
    idx = np.flatnonzero(pr.visible)
    idx = idx[np.argsort(pr.depth[idx], kind="stable")]
    xy, conic, opac = pr.xy[idx], pr.conic[idx], pr.opacity[idx]
    rgb_g, depth_g, inst_g = pr.rgb[idx], pr.depth[idx], g.instance_id[idx]
    h, w = cam.height, cam.width
    rgb = np.zeros((h, w, 3), np.float32)
    depth = np.zeros((h, w), np.float32)
    alpha_img = np.zeros((h, w), np.float32)
    inst = np.zeros((h, w), np.int32)
    bg = np.asarray(background, dtype=np.float64)
    for i in range(h):
        for j in range(w):
            dx, dy = xy[:, 0] - (j + 0.5), xy[:, 1] - (i + 0.5)
            power = -0.5 * (conic[:, 0] * dx * dx + conic[:, 2] * dy * dy) - conic[:, 1] * dx * dy
            alpha = np.minimum(MAX_ALPHA, opac * np.exp(power))
            use = np.flatnonzero((power <= 0) & (power >= -CUTOFF) & (alpha >= MIN_ALPHA))
            a = alpha[use]
            t_after = np.cumprod(1.0 - a)
            stop = np.flatnonzero(t_after < MIN_TRANSMITTANCE)
            n = stop[0] if len(stop) else len(a)
            a, use = a[:n], use[:n]
            t_before = np.concatenate([[1.0], t_after[: n - 1]]) if n else np.zeros(0)
            wts = a * t_before
            t_final = t_after[n - 1] if n else 1.0
            rgb[i, j] = wts @ rgb_g[use] + t_final * bg
            alpha_img[i, j] = 1.0 - t_final
            if n:
                depth[i, j] = (wts @ depth_g[use]) / (1.0 - t_final)
                inst[i, j] = inst_g[use[np.argmax(wts)]]
    return Frame(rgb=rgb, depth=depth, alpha=alpha_img, instance=inst)
