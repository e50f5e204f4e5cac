"""The Gaussians container: one frozen set of arrays in the conventions of the INRIA 3DGS PLY layout."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SH_C0 = 0.28209479177387814  # degree-0 real spherical harmonic; rgb = SH_C0 * f_dc + 0.5


@dataclass(frozen=True)
class Gaussians:
    """N anisotropic 3D Gaussians in world space (metres, Z up).

    means           [N, 3] float32  centres, m
    quats_wxyz      [N, 4] float32  rotation quaternion, w first (need not be unit; renderers normalise)
    log_scales      [N, 3] float32  natural log of the standard deviation along each local axis, m
    opacity_logits  [N] float32     opacity = sigmoid(logit)
    sh              [N, K, 3] float32  SH coefficients per RGB channel, K = (degree + 1)^2, DC first
    instance_id     [N] int32       the scene object the Gaussian belongs to; 0 = background
    """

    means: np.ndarray
    quats_wxyz: np.ndarray
    log_scales: np.ndarray
    opacity_logits: np.ndarray
    sh: np.ndarray
    instance_id: np.ndarray

    def __post_init__(self) -> None:
        n = len(self.means)
        expect = {
            "means": ((n, 3), np.float32),
            "quats_wxyz": ((n, 4), np.float32),
            "log_scales": ((n, 3), np.float32),
            "opacity_logits": ((n,), np.float32),
            "instance_id": ((n,), np.int32),
        }
        for name, (shape, dtype) in expect.items():
            arr = getattr(self, name)
            if arr.shape != shape or arr.dtype != dtype:
                raise ValueError(f"{name}: expected {shape} {np.dtype(dtype)}, got {arr.shape} {arr.dtype}")
        k = self.sh.shape[1] if self.sh.ndim == 3 else -1
        if self.sh.ndim != 3 or self.sh.shape[0] != n or self.sh.shape[2] != 3 or k not in (1, 4, 9, 16):
            raise ValueError(f"sh: expected ({n}, K, 3) with K in 1, 4, 9, 16, got {self.sh.shape}")
        if self.sh.dtype != np.float32:
            raise ValueError(f"sh: expected float32, got {self.sh.dtype}")

    @property
    def count(self) -> int:
        return len(self.means)

    @property
    def sh_degree(self) -> int:
        return int(round(np.sqrt(self.sh.shape[1]))) - 1

    def take(self, index: np.ndarray) -> Gaussians:
        """The Gaussians at `index` (an integer index array or a boolean mask [N])."""
        return Gaussians(
            means=self.means[index],
            quats_wxyz=self.quats_wxyz[index],
            log_scales=self.log_scales[index],
            opacity_logits=self.opacity_logits[index],
            sh=self.sh[index],
            instance_id=self.instance_id[index],
        )


def concat(parts: list[Gaussians]) -> Gaussians:
    """Join sets of Gaussians; lower SH degrees are zero-padded to the highest one."""
    if not parts:
        return empty()
    k = max(p.sh.shape[1] for p in parts)
    sh = [np.pad(p.sh, ((0, 0), (0, k - p.sh.shape[1]), (0, 0))) for p in parts]
    return Gaussians(
        means=np.concatenate([p.means for p in parts]),
        quats_wxyz=np.concatenate([p.quats_wxyz for p in parts]),
        log_scales=np.concatenate([p.log_scales for p in parts]),
        opacity_logits=np.concatenate([p.opacity_logits for p in parts]),
        sh=np.concatenate(sh),
        instance_id=np.concatenate([p.instance_id for p in parts]),
    )


def empty(sh_degree: int = 0) -> Gaussians:
    k = (sh_degree + 1) ** 2
    z = np.zeros
    return Gaussians(z((0, 3), np.float32), z((0, 4), np.float32), z((0, 3), np.float32), z(0, np.float32),
                     z((0, k, 3), np.float32), z(0, np.int32))


def dc_rgb(g: Gaussians) -> np.ndarray:
    """[N, 3] float64 in 0..1: each Gaussian's view-independent colour, SH_C0 * f_dc + 0.5 clipped."""
    return np.clip(SH_C0 * g.sh[:, 0, :].astype(np.float64) + 0.5, 0.0, 1.0)


def mean_colour(g: Gaussians) -> tuple[float, float, float]:
    """The mean dc_rgb of `g` (non-empty): the colour a set of Gaussians shows from afar."""
    r, gr, b = dc_rgb(g).mean(axis=0)
    return float(r), float(gr), float(b)


def rgb_to_sh_dc(rgb: np.ndarray) -> np.ndarray:
    """[..., 3] colour in [0, 1] -> the DC coefficient that renders as that colour."""
    return ((np.asarray(rgb, dtype=np.float64) - 0.5) / SH_C0).astype(np.float32)


def logit(p: np.ndarray | float) -> np.ndarray:
    p = np.asarray(p, dtype=np.float64)
    return np.log(p / (1.0 - p)).astype(np.float32)
