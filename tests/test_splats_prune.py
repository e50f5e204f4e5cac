"""Pruning: hidden and faint Gaussians score lowest and go first; what is seen is kept."""

from __future__ import annotations

import numpy as np
import pytest

from sagebench.render.camera import Camera
from sagebench.render.gaussians import Gaussians, logit, rgb_to_sh_dc
from sagebench.splats.prune import contribution_scores, prune, prune_lowest, psnr


def _scene() -> Gaussians:
    """A large opaque wall (id 1) at z=2 in front of 20 small Gaussians (ids 2..21) at z=5."""
    rng = np.random.default_rng(0)
    hidden = np.column_stack([rng.uniform(-0.5, 0.5, (20, 2)), np.full(20, 5.0)])
    means = np.vstack([[0, 0, 2.0], hidden, [[3.0, 0, 2.0]]])  # the last one is off to the side, visible
    n = len(means)
    scales = np.vstack([[2.0, 2.0, 0.01], np.full((20, 3), 0.05), [[0.1, 0.1, 0.01]]])
    return Gaussians(means.astype(np.float32), np.tile([1.0, 0, 0, 0], (n, 1)).astype(np.float32),
                     np.log(scales).astype(np.float32), logit(np.full(n, 0.999)),
                     rgb_to_sh_dc(rng.uniform(0, 1, (n, 3)))[:, None, :], np.arange(1, n + 1, dtype=np.int32))


def _cam() -> Camera:
    return Camera(64, 48, 20.0, 20.0, 32.0, 24.0, np.eye(4))


def test_hidden_gaussians_score_lowest_and_pruning_them_changes_nothing():
    g = _scene()
    scores = contribution_scores(g, [_cam()])
    assert scores[0] > scores[-1] > scores[1:21].max()
    pruned, report = prune(g, 20 / 22, [_cam()], [_cam()])
    assert sorted(pruned.instance_id.tolist()) == [1, 22]
    assert report.count_before == 22 and report.count_after == 2
    assert report.psnr_db > 60


def test_prune_lowest_keeps_order_and_count():
    g = _scene()
    scores = np.arange(g.count, dtype=np.float64)[::-1].copy()
    kept = prune_lowest(g, scores, 0.5)
    assert kept.instance_id.tolist() == list(range(1, 12))
    with pytest.raises(ValueError, match="fraction must be in"):
        prune_lowest(g, scores, 1.0)


def test_psnr():
    a = np.zeros((4, 4, 3))
    assert psnr(a, a) == float("inf")
    assert psnr(a, a + 0.1) == pytest.approx(20.0)
