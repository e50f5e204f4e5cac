"""Collider depth by ray casting against rendered splat depth: aligned layers agree, shifted or turned ones fail."""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest
import trimesh

from sagebench.replay.alignment import (
    collider_depth,
    collider_depth_reference,
    compare_depth,
    pixel_grid,
    ray_directions,
)
from sagebench.render.camera import agent_camera
from sagebench.render.gaussians import Gaussians
from sagebench.render.splat_render import render
from sagebench.splats.from_mesh import mesh_gaussians
from sagebench.splats.scene import quat_multiply

TOLERANCE = 0.10  # m, validate's default depth tolerance


@pytest.fixture(scope="module")
def wall():
    """A 6 m wide, 2.5 m tall wall slab at x = 2 as a MuJoCo mesh geom, and Gaussians sampled on its mesh."""
    mesh = trimesh.creation.box(extents=(0.1, 6.0, 2.5))
    mesh.apply_translation((2.05, 0.0, 1.25))
    verts = " ".join(f"{a} {b} {c}" for a, b, c in mesh.vertices)
    model = mujoco.MjModel.from_xml_string(
        f"<mujoco><asset><mesh name='w' vertex='{verts}'/></asset>"
        f"<worldbody><body name='wall_1'><geom type='mesh' mesh='w'/></body></worldbody></mujoco>")
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    gaussians = mesh_gaussians(mesh, 1, spacing=0.03, rng=np.random.default_rng(0))
    return model, data, gaussians


def _moved(g: Gaussians, yaw: float = 0.0, shift=(0.0, 0.0, 0.0)) -> Gaussians:
    """The Gaussians turned by `yaw` about the vertical axis through the origin, then shifted (m)."""
    c, s = math.cos(yaw), math.sin(yaw)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    means = (g.means.astype(np.float64) @ rot.T + np.asarray(shift)).astype(np.float32)
    q = np.array([math.cos(yaw / 2), 0, 0, math.sin(yaw / 2)])
    quats = quat_multiply(q, g.quats_wxyz.astype(np.float64)).astype(np.float32)
    return Gaussians(means, quats, g.log_scales, g.opacity_logits, g.sh, g.instance_id)


def _median_error(wall, gaussians):
    model, data, _ = wall
    cam = agent_camera(0.0, 0.0, 0.0, width=160, height=120, hfov_deg=90.0)
    grid = pixel_grid(cam, 4)
    frame = render(gaussians, cam)
    return compare_depth(frame.depth, frame.alpha, grid, collider_depth(model, data, cam, grid))


def test_aligned_gaussians_pass(wall):
    a = _median_error(wall, wall[2])
    assert a.compared > 0.5 * a.sampled  # the wall fills most of the view
    assert a.median_abs_diff < 0.02  # the splats' own thickness, well inside the tolerance


@pytest.mark.parametrize("yaw, shift", [(0.0, (0.3, 0.0, 0.0)), (0.0, (-0.3, 0.0, 0.0)), (math.radians(10), (0, 0, 0))])
def test_shifted_or_rotated_gaussians_fail(wall, yaw, shift):
    a = _median_error(wall, _moved(wall[2], yaw, shift))
    assert a.median_abs_diff > TOLERANCE


def test_multiray_matches_one_ray_at_a_time(wall):
    model, data, _ = wall
    cam = agent_camera(0.3, -0.4, 0.2, pitch_deg=-10.0, width=64, height=48, hfov_deg=90.0)
    grid = pixel_grid(cam, 3)
    fast = collider_depth(model, data, cam, grid)
    ref = collider_depth_reference(model, data, cam, grid)
    np.testing.assert_array_equal(np.isnan(fast), np.isnan(ref))
    np.testing.assert_allclose(fast[~np.isnan(fast)], ref[~np.isnan(ref)], atol=1e-9)
    assert np.isnan(fast).any() and (~np.isnan(fast)).any()  # rays above the wall miss it


def test_depth_is_along_the_optical_axis(wall):
    """Facing the wall square on, every hit is 2 m deep, wherever the pixel (not the slant range)."""
    model, data, _ = wall
    cam = agent_camera(0.0, 0.0, 0.0, width=40, height=30, hfov_deg=60.0)
    grid = pixel_grid(cam, 1)
    depth = collider_depth(model, data, cam, grid)
    np.testing.assert_allclose(depth, 2.0, atol=1e-9)
    dirs = ray_directions(cam, grid)
    np.testing.assert_allclose(dirs @ np.array([1.0, 0, 0]), 1.0)  # camera z is world +x here


def test_pixel_grid_is_centred_and_checks_stride():
    cam = agent_camera(0, 0, 0, width=10, height=6)
    g = pixel_grid(cam, 4)
    assert g.rows.tolist() == [2] and g.cols.tolist() == [2, 6]
    with pytest.raises(ValueError, match="stride must be >= 1"):
        pixel_grid(cam, 0)


def test_nothing_to_compare_gives_nan():
    cam = agent_camera(0, 0, 0, width=8, height=8)
    grid = pixel_grid(cam, 2)
    a = compare_depth(np.zeros((8, 8)), np.zeros((8, 8)), grid, np.full((4, 4), np.nan))
    assert a.compared == 0 and math.isnan(a.median_abs_diff)


@pytest.mark.parametrize("compared, fails", [(299, True), (300, False)])
def test_too_few_compared_pixels_fail_at_the_stated_minimum(compared, fails):
    from sagebench.replay.alignment import Alignment, frame_problem

    a = Alignment(median_abs_diff=0.01, compared=compared, sampled=1200)
    problem = frame_problem(a, tolerance=0.1, min_fraction=0.25)
    assert problem == (f"{compared} of 1200 sampled pixels compared, fewer than the minimum 300 (0.25 of them): "
                       "nothing to align with" if fails else None)


def test_no_compared_pixel_fails_and_a_far_median_fails():
    from sagebench.replay.alignment import Alignment, frame_problem

    assert frame_problem(Alignment(float("nan"), 0, 1200), tolerance=0.1, min_fraction=0.25).startswith(
        "0 of 1200 sampled pixels compared, fewer than the minimum 300")
    assert frame_problem(Alignment(0.1, 1200, 1200), tolerance=0.1, min_fraction=0.25) is None  # at the tolerance
    assert frame_problem(Alignment(0.1001, 1200, 1200), tolerance=0.1, min_fraction=0.25) == (
        "median depth difference 0.100 m > 0.1 m")
