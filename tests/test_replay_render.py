"""The splat renderers: analytic single Gaussian, occlusion and instance ids (float32 frames too), the fast
renderer's float64 reference == the numpy reference (also for faint, huge and needle-thin Gaussians, whose reach
ellipse decides which pixels the fast one visits), camera pose."""

from __future__ import annotations

import math
from functools import partial

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from profiles import examples

from sagebench.render.camera import Camera, agent_camera
from sagebench.render.gaussians import Gaussians, logit, rgb_to_sh_dc
from sagebench.render.sh import sh_basis
from sagebench.render.splat_reference import MIN_ALPHA, render_reference
from sagebench.render.splat_render import REFERENCE, contributions, render
from sagebench.splats.prune import psnr


def _gaussians(means, scales, rgb, opacity, ids, quats=None, sh_rest=None) -> Gaussians:
    n = len(means)
    sh = rgb_to_sh_dc(np.asarray(rgb, dtype=np.float64))[:, None, :]
    if sh_rest is not None:
        sh = np.concatenate([sh, sh_rest.astype(np.float32)], axis=1)
    return Gaussians(
        means=np.asarray(means, np.float32),
        quats_wxyz=np.asarray(quats if quats is not None else np.tile([1.0, 0, 0, 0], (n, 1)), np.float32),
        log_scales=np.log(np.asarray(scales, np.float64)).astype(np.float32),
        opacity_logits=logit(np.asarray(opacity, np.float64)),
        sh=sh,
        instance_id=np.asarray(ids, np.int32),
    )


render64 = partial(render, real=REFERENCE)  # the fast renderer's float64 reference, to the numpy one's precision


def _axis_camera(width: int, height: int, f: float) -> Camera:
    """At the origin looking along +z (x right, y down): world = camera frame."""
    return Camera(width, height, f, f, width / 2, height / 2, np.eye(4))


@pytest.mark.parametrize("renderer", [render, render64, render_reference])
def test_single_gaussian_head_on_is_the_expected_ellipse(renderer):
    d, f, sx, sy = 5.0, 100.0, 0.1, 0.05
    cam = _axis_camera(65, 49, f)  # odd sizes: the centre pixel's centre is the image centre
    g = _gaussians([[0, 0, d]], [[sx, sy, 1e-3]], [[0.2, 0.4, 0.6]], [0.8], [3])
    out = renderer(g, cam)
    var_x, var_y = (f * sx / d) ** 2 + 0.3, (f * sy / d) ** 2 + 0.3  # projected variance + 0.3 px^2
    assert out.alpha[24, 32] == pytest.approx(0.8, abs=1e-6)  # peak alpha = opacity at the centre
    assert out.rgb[24, 32].tolist() == pytest.approx([0.8 * 0.2, 0.8 * 0.4, 0.8 * 0.6], abs=1e-5)

    def expected(k: int, var: float) -> float:  # 0 beyond 3 sigma or below 1/255
        a = 0.8 * math.exp(-0.5 * k * k / var)
        return a if k * k <= 9 * var and a >= 1 / 255 else 0.0

    for k in range(1, 8):
        assert out.alpha[24, 32 + k] == pytest.approx(expected(k, var_x), abs=1e-6)
        assert out.alpha[24 - k, 32] == pytest.approx(expected(k, var_y), abs=1e-6)
    # the support ends at the 3-sigma ellipse: semi-axes 3 sqrt(var)
    assert out.alpha[24, 32 + math.floor(3 * math.sqrt(var_x))] > 0
    assert out.alpha[24, 32 + math.floor(3 * math.sqrt(var_x)) + 1] == 0
    assert out.alpha[24 + math.floor(3 * math.sqrt(var_y)) + 1, 32] == 0
    assert out.depth[24, 32] == pytest.approx(d, abs=1e-5)
    assert set(np.unique(out.instance[out.alpha > 0])) == {3}
    assert (out.instance[out.alpha == 0] == 0).all()


@pytest.mark.parametrize("renderer", [render, render64, render_reference])
def test_near_opaque_gaussian_hides_the_far_one(renderer):
    cam = _axis_camera(33, 33, 40.0)
    near = ([0, 0, 2.0], [0.15, 0.15, 0.01], [1.0, 0.0, 0.0], 0.999, 7)
    far = ([0, 0, 4.0], [1.0, 1.0, 0.01], [0.0, 1.0, 0.0], 0.999, 9)
    for order in ((far, near), (near, far)):  # array order must not matter, only depth
        g = _gaussians(*[list(x) for x in zip(*order)])
        out = renderer(g, cam)
        centre = out.rgb[16, 16]
        assert centre[0] > 0.98 and centre[1] < 0.02
        assert out.instance[16, 16] == 7
        assert out.depth[16, 16] == pytest.approx(2.0, abs=0.03)  # 1% of the far one leaks through
        assert out.instance[1, 1] == 9  # beyond the near one's 3 sigma, the far one shows


def _random_scene(n: int, seed: int) -> Gaussians:
    rng = np.random.default_rng(seed)
    means = rng.uniform([-2, -1.5, 1.0], [2, 1.5, 6.0], (n, 3))
    return _gaussians(means, rng.uniform(0.02, 0.4, (n, 3)), rng.uniform(0, 1, (n, 3)), rng.uniform(0.02, 1, n),
                      rng.integers(1, 100, n), quats=rng.normal(size=(n, 4)), sh_rest=rng.normal(0, 0.3, (n, 15, 3)))


def test_fast_renderer_matches_the_reference():
    g = _random_scene(1500, seed=1)
    cam = agent_camera(0.0, 0.0, 0.0, camera_height=0.0, width=80, height=60, hfov_deg=70)
    cam = Camera(80, 60, cam.fx, cam.fy, cam.cx, cam.cy, np.eye(4))
    fast, ref = render64(g, cam), render_reference(g, cam)
    # measured: 147.8 dB, |d alpha| 6e-8, |d depth| 1.2e-7 m (float32 rounding); a degree-3 SH coefficient
    # halved in the fast path drops it far below 140 dB
    assert psnr(fast.rgb, ref.rgb) >= 140.0
    assert np.abs(fast.alpha - ref.alpha).max() < 1e-6
    assert np.abs(fast.depth - ref.depth).max() < 1e-6
    assert (fast.instance == ref.instance).all()


def test_faint_huge_and_thin_gaussians_match_the_reference():
    """The fast renderer skips pixels outside each Gaussian's reach (3 sigma, shrunk to where opacity * exp(-d^2/2)
    reaches 1/255): opacities from just above 1/255 to 1, sizes up to metres across a frame, needles 100:1."""
    rng = np.random.default_rng(4)
    n = 500
    opacity = np.exp(rng.uniform(np.log(MIN_ALPHA * 1.001), 0.0, n))
    scales = np.exp(rng.uniform(np.log(0.005), np.log(2.0), (n, 3)))
    scales[::5, 0] *= 0.01  # needles and discs
    means = rng.uniform([-2, -1.5, 0.5], [2, 1.5, 5.0], (n, 3))
    g = _gaussians(means, scales, rng.uniform(0, 1, (n, 3)), opacity, rng.integers(1, 50, n),
                   quats=rng.normal(size=(n, 4)))
    cam = _axis_camera(48, 36, 30.0)
    fast, ref = render64(g, cam), render_reference(g, cam)
    # measured: 154.8 dB, |d alpha| 6e-8 (float32 rounding); 79 % of these Gaussians reach less than 3 sigma, and a
    # pixel dropped at a faint one's rim costs about 1/255 of alpha there
    assert psnr(fast.rgb, ref.rgb) >= 140.0
    assert np.abs(fast.alpha - ref.alpha).max() < 1e-6
    assert (fast.instance == ref.instance).all()


@settings(max_examples=examples(60))
@given(x=st.floats(-1.0, 1.0), y=st.floats(-1.0, 1.0), z=st.floats(0.3, 4.0),
       log_scales=st.tuples(*[st.floats(-5.0, 0.5)] * 3), quat=st.tuples(*[st.floats(-1.0, 1.0)] * 4),
       opacity=st.one_of(st.floats(MIN_ALPHA, 0.999), st.floats(MIN_ALPHA, MIN_ALPHA * 1.0001)))
def test_one_gaussian_covers_the_reference_pixels(x, y, z, log_scales, quat, opacity):
    """Every pixel the reference draws, the fast renderer draws, with the same alpha."""
    if np.linalg.norm(quat) < 1e-3:
        quat = (1.0, 0.0, 0.0, 0.0)
    g = _gaussians([[x, y, z]], [np.exp(log_scales)], [[0.5, 0.5, 0.5]], [opacity], [1], quats=[quat])
    cam = _axis_camera(32, 24, 20.0)
    fast, ref = render64(g, cam), render_reference(g, cam)
    assert ((fast.alpha > 0) == (ref.alpha > 0)).all()
    assert np.abs(fast.alpha - ref.alpha).max() < 1e-6


def test_sh_basis_is_orthonormal_on_the_sphere():
    # Gauss-Legendre in cos(theta) x uniform phi integrates products of degree <= 6 exactly
    mu, w_mu = np.polynomial.legendre.leggauss(8)
    phi = np.arange(16) * (2 * math.pi / 16)
    m, p = np.meshgrid(mu, phi, indexing="ij")
    s = np.sqrt(1 - m**2)
    dirs = np.column_stack([(s * np.cos(p)).ravel(), (s * np.sin(p)).ravel(), m.ravel()])
    w = np.repeat(w_mu, len(phi)) * (2 * math.pi / len(phi))
    y = sh_basis(dirs, 16)  # [N, 16]
    assert (y.T * w) @ y == pytest.approx(np.eye(16), abs=1e-12)


def test_contributions_add_up_to_the_alpha_image():
    g = _random_scene(400, seed=2)
    cam = _axis_camera(48, 40, 30.0)
    w = contributions(g, cam)
    assert w.shape == (g.count,) and (w >= 0).all()
    assert w.sum() == pytest.approx(float(render64(g, cam).alpha.sum()), rel=1e-4)


def test_agent_camera_looks_along_yaw_with_z_up():
    cam = agent_camera(1.0, 2.0, math.radians(30), floor_z=0.5, camera_height=1.2, width=64, height=48)
    assert cam.position.tolist() == pytest.approx([1.0, 2.0, 1.7])

    def pixel(p):
        q = cam.world_to_camera @ np.array([*p, 1.0])
        return cam.fx * q[0] / q[2] + cam.cx, cam.fy * q[1] / q[2] + cam.cy, q[2]

    ahead = [1.0 + 3 * math.cos(math.radians(30)), 2.0 + 3 * math.sin(math.radians(30)), 1.7]
    assert pixel(ahead) == pytest.approx((32.0, 24.0, 3.0))
    left = [ahead[0] - 0.5 * math.sin(math.radians(30)), ahead[1] + 0.5 * math.cos(math.radians(30)), 1.7]
    assert pixel(left)[0] < 32.0  # counter-clockwise of the heading is the image's left
    assert pixel([*ahead[:2], 2.0])[1] < 24.0  # up is the image's top
    # 90 degrees hfov: a point 45 degrees off-axis is at the image edge
    edge = [1.0 + 3 * math.cos(math.radians(-15)), 2.0 + 3 * math.sin(math.radians(-15)), 1.7]
    assert pixel(edge)[0] == pytest.approx(64.0)
    up = agent_camera(0, 0, 0, camera_height=1.0, pitch_deg=20, width=64, height=48)
    q = up.world_to_camera @ np.array([math.cos(math.radians(20)), 0, 1.0 + math.sin(math.radians(20)), 1.0])
    assert q[:2].tolist() == pytest.approx([0.0, 0.0], abs=1e-12)
