"""The one place sagebench's conventions meet gsplat's (render/gsplat_convention.py), checked against the CPU
renderer's own conventions on known cases: what the conversion produces is fed to gsplat's math written in numpy
(tests/gsplat_numpy.py, as gsplat's _torch_impl and kernels define it), so no CUDA device is needed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sagebench.render.camera import Camera, agent_camera
from sagebench.render.gaussians import Gaussians, logit, rgb_to_sh_dc
from sagebench.render.gsplat_convention import camera_arrays, frames_from_gsplat, raster_settings, scene_arrays
from sagebench.render.splat_reference import project, render_reference
from tests import gsplat_numpy


def _gaussians(n: int, degree: int, seed: int, *, opacity: tuple[float, float] = (0.05, 0.95)) -> Gaussians:
    """n anisotropic, rotated Gaussians 1.5-4 m in front of an agent at the origin looking along +X."""
    rng = np.random.default_rng(seed)
    means = np.column_stack([rng.uniform(1.5, 4.0, n), rng.uniform(-1.5, 1.5, n), rng.uniform(0.4, 2.0, n)])
    sh = rng.normal(0.0, 0.3, (n, (degree + 1) ** 2, 3))
    return Gaussians(means=means.astype(np.float32),
                     quats_wxyz=rng.normal(size=(n, 4)).astype(np.float32) * 1.7,  # not unit: both normalise
                     log_scales=rng.uniform(-3.5, -1.5, (n, 3)).astype(np.float32),
                     opacity_logits=logit(rng.uniform(*opacity, n)), sh=sh.astype(np.float32),
                     instance_id=np.arange(1, n + 1, dtype=np.int32))


def _gsplat_project(g: Gaussians, cam: Camera):
    s, c = scene_arrays(g), camera_arrays([cam])
    settings = raster_settings()
    return gsplat_numpy.project(s.means, s.quats, s.scales, s.opacities, c.viewmats[0], c.Ks[0], c.width, c.height,
                                near_plane=settings["near_plane"], eps2d=settings["eps2d"]), s


CAMERAS = {
    "level": agent_camera(0.0, 0.0, 0.0, width=64, height=48, hfov_deg=90.0),
    "turned and tilted": agent_camera(0.3, -0.2, 0.35, pitch_deg=-12.0, width=48, height=48, hfov_deg=70.0),
    "raised floor": agent_camera(0.0, 0.1, -0.2, floor_z=0.5, camera_height=0.6, width=40, height=30),
}


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
@pytest.mark.parametrize("view", sorted(CAMERAS))
def test_projection_and_colour_match_the_cpu_renderer(degree, view):
    """Quaternion order, log-scales, logit opacity, SH of every degree, intrinsics and extrinsics: gsplat's
    projection of the converted arrays gives the CPU reference's centres, conics, depths, colours, opacities."""
    g, cam = _gaussians(40, degree, seed=degree), CAMERAS[view]
    (means2d, conics, depths, radii), s = _gsplat_project(g, cam)
    ref = project(g, cam)
    assert s.sh_degree == degree
    np.testing.assert_allclose(means2d, ref.xy, rtol=1e-5, atol=1e-4)
    np.testing.assert_allclose(depths, ref.depth, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(conics, ref.conic, rtol=1e-4, atol=1e-7)
    np.testing.assert_allclose(s.opacities, ref.opacity, rtol=1e-6)
    k = (degree + 1) ** 2
    cam_pos = np.linalg.inv(camera_arrays([cam]).viewmats[0].astype(np.float64))[:3, 3]
    dirs = s.means.astype(np.float64) - cam_pos
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    rgb = np.maximum(np.einsum("nk,nkc->nc", gsplat_numpy.sh_basis(k, dirs), s.colors.astype(np.float64)) + 0.5, 0)
    np.testing.assert_allclose(rgb, ref.rgb, atol=1e-5)
    on_screen = ref.visible & (ref.xy >= 0).all(axis=1) & (ref.xy < [cam.width, cam.height]).all(axis=1)
    assert on_screen.sum() >= 5 and (radii[on_screen] > 0).all()


def test_the_world_is_z_up_on_both_sides():
    """A Gaussian above the camera's height lands in the upper half of the image (rows < cy) in both, one to the
    agent's left in the left half."""
    cam = agent_camera(0.0, 0.0, 0.0, width=64, height=48)
    g = Gaussians(means=np.array([[3.0, 0.0, 2.2], [3.0, 1.0, 1.2]], np.float32),
                  quats_wxyz=np.tile(np.float32([1, 0, 0, 0]), (2, 1)), log_scales=np.full((2, 3), -3, np.float32),
                  opacity_logits=logit(np.full(2, 0.5)), sh=np.zeros((2, 1, 3), np.float32),
                  instance_id=np.array([1, 2], np.int32))
    (means2d, *_), _ = _gsplat_project(g, cam)
    ref = project(g, cam)
    assert means2d[0, 1] < cam.cy and ref.xy[0, 1] < cam.cy
    assert means2d[1, 0] < cam.cx and ref.xy[1, 0] < cam.cx


@pytest.mark.parametrize(("distance", "drawn"), [(0.005, False), (0.02, True)])
def test_the_near_plane_culls_alike(distance, drawn):
    cam = agent_camera(0.0, 0.0, 0.0, width=32, height=32)
    g = Gaussians(means=np.array([[distance, 0.0, 1.2]], np.float32), quats_wxyz=np.float32([[1, 0, 0, 0]]),
                  log_scales=np.full((1, 3), -6, np.float32), opacity_logits=logit(np.array([0.5])),
                  sh=np.zeros((1, 1, 3), np.float32), instance_id=np.array([1], np.int32))
    (_, _, _, radii), _ = _gsplat_project(g, cam)
    assert bool((radii[0] > 0).any()) == drawn == bool(project(g, cam).visible[0])


def test_rendered_colour_alpha_and_expected_depth_match_the_cpu_reference():
    """Faint Gaussians (opacity below 0.35, where neither renderer's support cut-off nor alpha cap matters) at
    several depths: gsplat's compositing of the converted scene gives the CPU reference frame, the expected depth
    included, for two cameras in one call."""
    g = _gaussians(30, 2, seed=7, opacity=(0.05, 0.3))
    cams = [CAMERAS["level"].scaled(32, 24), CAMERAS["turned and tilted"].scaled(32, 24)]
    s, c = scene_arrays(g), camera_arrays(cams)
    background = np.float32([0.2, 0.3, 0.4])
    colors, alphas, _ = gsplat_numpy.rasterization(
        s.means, s.quats, s.scales, s.opacities, s.colors, c.viewmats, c.Ks, c.width, c.height,
        sh_degree=s.sh_degree, backgrounds=np.tile(background, (2, 1)), **raster_settings())
    for frame, cam in zip(frames_from_gsplat(colors, alphas), cams):
        ref = render_reference(g, cam, background=tuple(background))
        assert ref.alpha.max() > 0.25  # something is drawn
        np.testing.assert_allclose(frame.rgb, ref.rgb, atol=2e-5)
        np.testing.assert_allclose(frame.alpha, ref.alpha, atol=2e-5)
        np.testing.assert_allclose(frame.depth, ref.depth, rtol=1e-4, atol=1e-5)
        assert frame.instance is None


def test_frames_from_gsplat_give_no_depth_where_nothing_was_drawn():
    colors = np.zeros((1, 2, 2, 4), np.float32)
    colors[0, 0, 0] = [0.1, 0.2, 0.3, 2.5]
    colors[0, 1, 1, 3] = 7.0  # gsplat's 0 / 1e-10 where alpha is 0 can be anything
    alphas = np.zeros((1, 2, 2, 1), np.float32)
    alphas[0, 0, 0, 0] = 0.5
    (frame,) = frames_from_gsplat(colors, alphas)
    assert frame.depth.tolist() == [[2.5, 0.0], [0.0, 0.0]]
    assert frame.rgb[0, 0].tolist() == pytest.approx([0.1, 0.2, 0.3])


def test_camera_arrays_are_opencv_intrinsics_and_world_to_camera():
    cam = agent_camera(1.0, 2.0, math.pi / 2, width=40, height=20, hfov_deg=90.0)
    c = camera_arrays([cam, cam])
    assert c.viewmats.shape == (2, 4, 4) and c.Ks.shape == (2, 3, 3) and (c.width, c.height) == (40, 20)
    np.testing.assert_allclose(c.Ks[0], [[20, 0, 20], [0, 20, 10], [0, 0, 1]])
    np.testing.assert_allclose(c.viewmats[1] @ np.array([1.0, 5.0, 1.2, 1.0]), [0, 0, 3, 1], atol=1e-6)  # ahead
    with pytest.raises(ValueError, match="one image size"):
        camera_arrays([cam, cam.scaled(20, 10)])


def test_scene_arrays_convert_each_parameter():
    g = Gaussians(means=np.float32([[1, 2, 3]]), quats_wxyz=np.float32([[0.5, 0.5, 0.5, 0.5]]),
                  log_scales=np.float32([[0.0, math.log(2.0), -1.0]]), opacity_logits=np.float32([0.0]),
                  sh=rgb_to_sh_dc(np.array([[[0.5, 0.25, 1.0]]])), instance_id=np.int32([9]))
    s = scene_arrays(g)
    np.testing.assert_allclose(s.scales, [[1.0, 2.0, math.exp(-1.0)]], rtol=1e-6)
    np.testing.assert_allclose(s.opacities, [0.5])
    assert s.quats.tolist() == [[0.5, 0.5, 0.5, 0.5]] and s.sh_degree == 0
    assert all(a.dtype == np.float32 for a in (s.means, s.quats, s.scales, s.opacities, s.colors))
