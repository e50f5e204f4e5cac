"""Chunk culling: a culled chunk holds no Gaussian the renderer would draw, and culled frames (several cameras
rendered side by side) equal plain ones."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sagebench.render.camera import agent_camera
from sagebench.render.chunks import pack, visible_chunks, visible_index
from sagebench.render.gaussians import Gaussians, logit, rgb_to_sh_dc
from sagebench.render.splat_reference import render_reference
from sagebench.render.splat_render import (
    RECORD,
    REFERENCE,
    _bin,
    _concurrent_launches,
    _depth_order,
    _project,
    _project_fast,
    render,
    render_packed,
)
from sagebench.splats.prune import psnr


def _room(n: int, seed: int) -> Gaussians:
    """Gaussians of 40 objects scattered over a 10 x 10 m floor, 0-2.5 m up, some large."""
    rng = np.random.default_rng(seed)
    ids = rng.integers(1, 41, n).astype(np.int32)
    centres = rng.uniform([-5, -5, 0], [5, 5, 2.5], (41, 3))
    means = centres[ids] + rng.normal(0, 0.6, (n, 3))
    scales = np.exp(rng.uniform(np.log(0.01), np.log(0.5), (n, 3)))
    sh = np.concatenate([rgb_to_sh_dc(rng.uniform(0, 1, (n, 3)))[:, None], rng.normal(0, 0.2, (n, 3, 3))], axis=1)
    return Gaussians(means.astype(np.float32), rng.normal(size=(n, 4)).astype(np.float32),
                     np.log(scales).astype(np.float32), logit(rng.uniform(0.05, 0.99, n)), sh.astype(np.float32), ids)


def _cams(width: int = 64, height: int = 48):
    return [agent_camera(x, y, yaw, camera_height=1.2, width=width, height=height, hfov_deg=hfov)
            for x, y, yaw, hfov in [(0, 0, 0.0, 90), (-4, -4, math.pi / 4, 60), (4.5, 0, math.pi, 120),
                                    (0, 4.8, -math.pi / 2, 90), (-4.9, 2, 0.3, 30)]]


def test_pack_keeps_every_gaussian_and_makes_chunks_contiguous():
    g = _room(3000, seed=0)
    p = pack(g, cell=1.0)
    assert p.gaussians.count == g.count and p.starts[0] == 0 and p.starts[-1] == g.count
    for c in range(p.chunks):
        part = p.gaussians.take(np.arange(p.starts[c], p.starts[c + 1]))
        assert len(set(part.instance_id.tolist())) == 1  # one object
        cells = np.unique(np.floor(part.means / 1.0), axis=0)
        assert len(cells) == 1  # one cell
        assert (part.means >= p.lo[c] - 1e-6).all() and (part.means <= p.hi[c] + 1e-6).all()
    # same multiset of Gaussians
    key = lambda x: np.sort(x.means.view(np.uint32).reshape(len(x.means), 3), axis=0)  # noqa: E731
    assert (key(g) == key(p.gaussians)).all()


@pytest.mark.parametrize("project", [_project, _project_fast], ids=["reference", "float32"])
def test_culled_chunks_hold_no_gaussian_the_renderer_draws(project):
    p = pack(_room(6000, seed=1), cell=1.0)
    g = p.gaussians
    culled_any = 0
    for cam in _cams():
        keep = visible_chunks(p, cam)
        culled_any += int((~keep).sum())
        rows = np.arange(g.count)
        rect = project(rows, g.means, g.quats_wxyz, g.log_scales, g.opacity_logits, g.sh,
                        np.ascontiguousarray(cam.world_to_camera), float(cam.fx), float(cam.fy), float(cam.cx),
                        float(cam.cy), cam.width, cam.height,
                        np.empty((g.count, RECORD), np.float32 if project is _project_fast else np.float64))
        drawn_chunk = np.searchsorted(p.starts, np.flatnonzero(rect[:, 0] >= 0), side="right") - 1
        assert keep[drawn_chunk].all()
    assert culled_any > 0.2 * p.chunks * len(_cams())  # the cull does cut (measured: 28 % of chunk-views)


def test_culled_frames_equal_plain_frames_byte_for_byte():
    """Also when the cameras render side by side, one per thread."""
    p = pack(_room(6000, seed=2), cell=1.0)
    cams = _cams()
    plains = [render(p.gaussians, cam) for cam in cams]
    assert _concurrent_launches()  # the plain renders picked numba's threading layer: the batch goes threaded
    for cam, frame, plain in zip(cams, render_packed(p, cams), plains):
        for name in ("rgb", "depth", "alpha", "instance"):
            assert getattr(frame, name).tobytes() == getattr(plain, name).tobytes()
        assert len(visible_index(p, cam)) < p.gaussians.count


def test_culled_frame_matches_the_reference_renderer():
    p = pack(_room(1500, seed=3), cell=1.0)
    cam = _cams(40, 30)[1]
    fast, ref = render_packed(p, [cam], real=REFERENCE)[0], render_reference(p.gaussians, cam)
    assert psnr(fast.rgb, ref.rgb) >= 140.0
    assert (fast.instance == ref.instance).all()


def test_depth_order_is_numpys_stable_argsort():
    """The radix depth sort (of float64 and float32 depths' bits) against np.argsort(kind="stable"): ties (rounded
    depths) keep index order, depths spanning many binades, and the empty and one-element cases; on one thread
    and in parallel slices."""
    rng = np.random.default_rng(3)
    cases = [np.zeros(0), np.array([2.5]), np.round(rng.uniform(0.01, 20.0, 50000), 2),
             np.exp(rng.uniform(np.log(1e-2), np.log(1e6), 50000)), np.full(20000, 0.75)]
    for d in cases + [c.astype(np.float32) for c in cases]:
        bits = d.view(np.uint64 if d.dtype == np.float64 else np.uint32)
        for threads in (1, 3):
            assert np.array_equal(_depth_order(bits, threads), np.argsort(d, kind="stable"))


def test_binning_lists_each_tile_in_the_given_order():
    """Every tile's run holds exactly the Gaussians whose rectangle covers it, in `order`; the same when slices
    of `order` are counted and placed in parallel."""
    rng = np.random.default_rng(5)
    n, gx, gy = 30000, 14, 11
    x0, y0 = rng.integers(0, gx, n), rng.integers(0, gy, n)
    rect = np.column_stack([x0, np.minimum(x0 + rng.integers(1, 4, n), gx),
                            y0, np.minimum(y0 + rng.integers(1, 4, n), gy)]).astype(np.int32)
    order = rng.permutation(n)
    r = rect[order]
    for threads in (1, 3):
        offsets, pairs = _bin(order, rect, gx, gx * gy, threads)
        for t in range(gx * gy):
            tx, ty = t % gx, t // gx
            covers = (r[:, 0] <= tx) & (tx < r[:, 1]) & (r[:, 2] <= ty) & (ty < r[:, 3])
            assert np.array_equal(pairs[offsets[t]:offsets[t + 1]], order[covers])
