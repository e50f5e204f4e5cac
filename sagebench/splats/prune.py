"""Contribution-based pruning: drop the Gaussians that add least to a set of views (LightGaussian idea).

A Gaussian's score is its blending weight alpha * T summed over every pixel of every scoring view;
Gaussians that are hidden, off-view or faint score near zero and go first.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sagebench.render.camera import Camera
from sagebench.render.gaussians import Gaussians
from sagebench.render.splat_render import REFERENCE, contributions, render


@dataclass(frozen=True)
class PruneReport:
    """What pruning cost: `psnr_db` of pruned vs unpruned renders over the held-out views (pooled MSE)."""

    fraction: float
    count_before: int
    count_after: int
    psnr_db: float


def contribution_scores(g: Gaussians, cameras: list[Camera]) -> np.ndarray:
    """[N] float64 summed blending weight of each Gaussian over `cameras`."""
    scores = np.zeros(g.count)
    for cam in cameras:
        scores += contributions(g, cam)
    return scores


def prune_lowest(g: Gaussians, scores: np.ndarray, fraction: float) -> Gaussians:
    """Keep all but the round(fraction * N) lowest-scoring Gaussians (ties: lower index kept), in order."""
    if not 0.0 <= fraction < 1.0:
        raise ValueError(f"fraction must be in [0, 1), got {fraction}")
    drop = int(round(fraction * g.count))
    order = np.argsort(-scores, kind="stable")
    return g.take(np.sort(order[: g.count - drop]))


def mse(a: np.ndarray, b: np.ndarray) -> float:
    """Mean squared error of two images after clipping to [0, 1]."""
    return float(np.mean((np.clip(a, 0, 1).astype(np.float64) - np.clip(b, 0, 1)) ** 2))


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    """PSNR in dB of two images with values in [0, 1] (clipped); inf when equal."""
    return psnr_from_mse(mse(a, b))


def psnr_from_mse(value: float) -> float:
    return float("inf") if value == 0 else float(10.0 * np.log10(1.0 / value))


def prune(g: Gaussians, fraction: float, scoring: list[Camera], held_out: list[Camera]) -> tuple[Gaussians, PruneReport]:
    """Prune `fraction` of `g` by contribution over `scoring` views; report PSNR on `held_out` views."""
    pruned = prune_lowest(g, contribution_scores(g, scoring), fraction)
    errors = [mse(render(pruned, cam, real=REFERENCE, ids=False).rgb, render(g, cam, real=REFERENCE, ids=False).rgb)
              for cam in held_out]
    score = psnr_from_mse(float(np.mean(errors))) if errors else float("nan")
    return pruned, PruneReport(fraction, g.count, pruned.count, score)
