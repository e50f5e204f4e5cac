"""Renderer backends: which one `auto`, `cpu` and `gsplat` pick, the CPU backend's frames unchanged, and the gsplat
backend's plumbing (one call for every view, frames back) with gsplat's math in numpy standing in for its kernel."""

from __future__ import annotations

import contextlib
import math
import types

import numpy as np
import pytest

from sagebench.errors import ConfigError
from sagebench.render import backends
from sagebench.render.backends import CpuRenderer, GsplatRenderer, choose_backend, open_renderer
from sagebench.render.camera import agent_camera, agent_cameras
from sagebench.render.chunks import pack
from sagebench.render.observations import masked_depth, observation_arrays, to_uint8
from sagebench.render.splat_render import MAX_SIDE, render, render_packed
from tests import gsplat_numpy
from tests.test_render_gsplat_convention import _gaussians


@pytest.fixture
def no_gsplat(monkeypatch):
    monkeypatch.setattr(backends, "gsplat_missing", lambda: "torch is not installed (pip install 'sagebench[gpu]')")


@pytest.fixture
def gsplat_here(monkeypatch):
    monkeypatch.setattr(backends, "gsplat_missing", lambda: None)


@pytest.mark.parametrize(("choice", "needs", "picked"), [
    ("cpu", ("rgb",), "cpu"), ("auto", ("rgb", "depth"), "cpu"), ("auto", ("rgb", "instance"), "cpu")])
def test_without_gsplat_auto_is_the_cpu(no_gsplat, choice, needs, picked):
    assert choose_backend(choice, needs) == picked


@pytest.mark.parametrize(("needs", "picked"), [(("rgb", "depth"), "gsplat"), (("rgb",), "gsplat"),
                                               (("rgb", "depth", "instance"), "cpu"), ((), "gsplat")])
def test_with_gsplat_auto_takes_it_for_what_it_draws(gsplat_here, needs, picked):
    assert choose_backend("auto", needs) == picked
    assert choose_backend("cpu", needs) == "cpu"


def test_an_explicit_gsplat_that_cannot_run_is_one_line(no_gsplat):
    with pytest.raises(ConfigError) as err:
        choose_backend("gsplat", ("rgb",))
    assert str(err.value) == ("--renderer: the gsplat renderer cannot run here: torch is not installed "
                              "(pip install 'sagebench[gpu]')")


def test_gsplat_asked_for_instance_ids_is_one_line(gsplat_here):
    with pytest.raises(ConfigError) as err:
        choose_backend("gsplat", ("rgb", "instance"))
    assert str(err.value) == "--renderer: the gsplat renderer draws no instance images; use --renderer cpu or auto"


def test_an_unknown_backend_is_one_line():
    with pytest.raises(ConfigError) as err:
        choose_backend("vulkan", ())
    assert str(err.value) == "--renderer: 'vulkan' is not one of auto, cpu, gsplat"


def test_gsplat_missing_names_what_to_install(monkeypatch):
    monkeypatch.setattr(backends.importlib.util, "find_spec", lambda name: None)
    assert backends.gsplat_missing() == "torch is not installed (pip install 'sagebench[gpu]')"


def test_the_cpu_backend_draws_what_the_cpu_renderer_draws():
    g = _gaussians(60, 1, seed=3)
    cams = [agent_camera(0.0, 0.0, yaw, width=40, height=30) for yaw in (0.0, 0.2, -0.3)]
    packed = pack(g)
    for got, want in zip(CpuRenderer(packed).render(cams), render_packed(packed, cams)):
        assert all(np.array_equal(getattr(got, k), getattr(want, k)) for k in ("rgb", "depth", "alpha", "instance"))
    for got, cam in zip(open_renderer(g, "cpu", needs=("instance",)).render(cams), cams):
        assert np.array_equal(got.rgb, render(g, cam).rgb) and np.array_equal(got.instance, render(g, cam).instance)


def test_observations_convert_known_values():
    """uint8 RGB rounds half up after clipping (as the render stage's PNGs); depth is 0 where nothing was drawn."""
    rgb = np.array([-0.1, 0.0, 0.5 / 255, 0.49 / 255, 254.5 / 255, 1.0, 1.7], np.float32)
    assert to_uint8(rgb).tolist() == [0, 0, 1, 0, 255, 255, 255]
    depth, alpha = np.array([2.0, 3.0, 4.0], np.float32), np.array([0.5, 0.0, 1e-9], np.float32)
    assert masked_depth(depth, alpha).tolist() == [2.0, 0.0, 4.0]
    with pytest.raises(ValueError, match="unknown image 'normals'"):
        CpuRenderer(_gaussians(3, 1, seed=1)).observe([agent_camera(0.0, 0.0, 0.0, width=8, height=6)], ("normals",))


def test_the_cpu_backends_observations_are_its_frames_converted_byte_for_byte():
    g = pack(_gaussians(60, 1, seed=3))
    cams = [agent_camera(0.0, 0.0, yaw, width=40, height=30) for yaw in (0.0, 0.2, -0.3)]
    frames = CpuRenderer(g).render(cams)
    got = CpuRenderer(g).observe(cams, ("rgb", "depth", "alpha", "instance"))
    assert {k: (v.shape, v.dtype) for k, v in got.items()} == {
        "rgb": ((3, 30, 40, 3), np.uint8), "depth": ((3, 30, 40), np.float32), "alpha": ((3, 30, 40), np.float32),
        "instance": ((3, 30, 40), np.int32)}
    for k, f in enumerate(frames):
        assert got["rgb"][k].tobytes() == to_uint8(f.rgb).tobytes()
        assert got["depth"][k].tobytes() == f.depth.astype(np.float32).tobytes()  # the CPU's depth is already 0
        assert got["instance"][k].tobytes() == f.instance.astype(np.int32).tobytes()  # where nothing was drawn
    assert list(CpuRenderer(g).observe(cams[:1], ("depth",))) == ["depth"]


def test_observations_without_instance_ids_skip_drawing_them_and_are_the_same_bytes(monkeypatch):
    """The env's RGB + depth: no ids drawn (the frames' instance is None), every other image byte-identical."""
    g = pack(_gaussians(60, 1, seed=4))
    cams = [agent_camera(0.0, 0.0, yaw, width=40, height=30) for yaw in (0.0, 0.4)]
    asked = []
    render_as_is = CpuRenderer.render
    monkeypatch.setattr(CpuRenderer, "render", lambda self, cams, ids=True: asked.append(ids) or render_as_is(
        self, cams, ids))
    full = CpuRenderer(g).observe(cams, ("rgb", "depth", "alpha", "instance"))
    lean = CpuRenderer(g).observe(cams, ("rgb", "depth", "alpha"))
    assert asked == [True, False]
    assert (full["instance"] > 0).any()  # the scene has ids to draw
    assert all(lean[k].tobytes() == full[k].tobytes() for k in ("rgb", "depth", "alpha"))
    assert {f.instance is None for f in render_as_is(CpuRenderer(g), cams, ids=False)} == {True}


def test_a_view_wider_than_the_renderer_draws_is_one_clear_error():
    cam = agent_camera(0.0, 0.0, 0.0, width=MAX_SIDE + 1, height=4)
    with pytest.raises(ValueError, match=f"a {MAX_SIDE + 1}x4 view: the renderer draws at most {MAX_SIDE} pixels a "
                                         "side"):
        render(_gaussians(3, 1, seed=1), cam)


@pytest.mark.parametrize(("cams", "keys", "message"), [
    ([], ("rgb",), "no cameras to observe from"),
    ([agent_camera(0.0, 0.0, 0.0, width=8, height=6), agent_camera(0.0, 0.0, 0.0, width=6, height=6)], ("rgb",),
     "one observe call takes cameras of one image size, got [(6, 6), (8, 6)]"),
    ([agent_camera(0.0, 0.0, 0.0, width=8, height=6)], ("rgb", "instance"), "the gsplat renderer draws no instance"),
])
def test_a_bad_observe_call_is_refused_before_rendering(gsplat_here, monkeypatch, cams, keys, message):
    monkeypatch.setattr(backends, "load_gsplat", lambda: (_fake_torch(), None))  # no kernel: nothing may render
    with pytest.raises(ValueError) as err:
        GsplatRenderer(_gaussians(3, 1, seed=1)).observe(cams, keys)
    assert str(err.value).startswith(message)


class _Tensor(np.ndarray):
    """Enough of a torch tensor for GsplatRenderer: numpy underneath."""

    def to(self, device):
        return self

    def cpu(self):
        return self

    def numpy(self):
        return np.asarray(self)

    def expand(self, *shape):
        return np.broadcast_to(self, shape).view(_Tensor)

    def copy_(self, src, non_blocking=False):
        self[...] = src
        return self


def _t(a) -> _Tensor:
    return np.asarray(a).view(_Tensor)


def _fake_torch():
    return types.SimpleNamespace(
        float32=np.float32, uint8=np.uint8, int32=np.int32, no_grad=contextlib.nullcontext,
        from_numpy=_t, tensor=lambda v, dtype, device: _t(np.asarray(v, dtype=dtype)),
        clip=lambda a, lo, hi: _t(np.clip(a, lo, hi)), where=lambda c, a, b: _t(np.where(c, a, b)),
        zeros_like=lambda a: _t(np.zeros_like(a)), asarray=lambda a, dtype: _t(np.asarray(a, dtype=dtype)),
        empty=lambda shape, dtype, pin_memory: _t(np.empty(shape, dtype)),
        cuda=types.SimpleNamespace(current_stream=lambda: types.SimpleNamespace(synchronize=lambda: None)))


def test_the_gsplat_backend_renders_every_view_in_one_call(gsplat_here, monkeypatch):
    """With gsplat's math in numpy for its kernel, the backend converts once, renders all views in one call and
    gives the CPU reference's frames (faint Gaussians: where both renderers' support and alpha rules agree)."""
    calls = []

    def rasterization(**kw):
        calls.append(len(kw["viewmats"]))
        colors, alphas, meta = gsplat_numpy.rasterization(**kw)
        return colors.view(_Tensor), alphas.view(_Tensor), meta

    monkeypatch.setattr(backends, "load_gsplat", lambda: (_fake_torch(), rasterization))
    g = _gaussians(25, 1, seed=5, opacity=(0.05, 0.3))
    cams = [agent_camera(0.0, 0.0, yaw, width=24, height=16) for yaw in (0.0, 0.25, -0.25)]
    renderer = open_renderer(pack(g), "auto", needs=("rgb", "depth"))
    assert isinstance(renderer, GsplatRenderer)
    frames = renderer.render(cams)
    assert calls == [3]
    from sagebench.render.splat_reference import render_reference

    for frame, cam in zip(frames, cams):
        ref = render_reference(g, cam)
        np.testing.assert_allclose(frame.rgb, ref.rgb, atol=2e-5)
        np.testing.assert_allclose(frame.depth, ref.depth, rtol=1e-4, atol=1e-5)
    assert renderer.render([]) == [] and calls == [3]


def test_the_gsplat_backends_observations_are_its_frames_converted_in_one_call(gsplat_here, monkeypatch):
    """observe: one rasterization for every view, converted where the frames are (torch's ops, numpy standing in),
    equal to render()'s frames converted on the host; the arrays are the caller's, untouched by a later call."""
    calls = []

    def rasterization(**kw):
        calls.append(len(kw["viewmats"]))
        colors, alphas, meta = gsplat_numpy.rasterization(**kw)
        return colors.view(_Tensor), alphas.view(_Tensor), meta

    monkeypatch.setattr(backends, "load_gsplat", lambda: (_fake_torch(), rasterization))
    g = _gaussians(25, 1, seed=5, opacity=(0.05, 0.3))
    cams = [agent_camera(0.0, 0.0, yaw, width=24, height=16) for yaw in (0.0, 0.25, -0.25)]
    renderer = GsplatRenderer(pack(g))
    got = renderer.observe(cams, ("rgb", "depth", "alpha"))
    assert calls == [3] and all(type(v) is np.ndarray for v in got.values())
    frames = renderer.render(cams)
    want = observation_arrays({f: np.stack([getattr(fr, f) for fr in frames]) for f in ("rgb", "depth", "alpha")},
                              ("rgb", "depth", "alpha"))
    assert {k: v.tobytes() for k, v in got.items()} == {k: v.tobytes() for k, v in want.items()}
    assert (got["depth"][got["alpha"] == 0] == 0).all() and (got["alpha"] == 0).any()  # masked where undrawn
    kept = {k: v.copy() for k, v in got.items()}
    renderer.observe(cams[::-1], ("rgb", "depth", "alpha"))
    assert all(np.array_equal(got[k], kept[k]) for k in got)


def test_a_batch_of_agent_cameras_is_each_agents_camera_byte_for_byte():
    poses = np.array([[0.3, -1.2, 0.0, 0.7], [2.0, 1.0, 0.0, -2.9], [-0.5, 0.25, 0.0, math.pi / 2]])
    cams = agent_cameras(poses, floor_z=0.1, camera_height=1.25, pitch_deg=-10.0, hfov_deg=79.0, width=32, height=24)
    for cam, (x, y, _, yaw) in zip(cams, poses):
        one = agent_camera(x, y, yaw, floor_z=0.1, camera_height=1.25, pitch_deg=-10.0, hfov_deg=79.0, width=32,
                           height=24)
        assert cam.world_to_camera.tobytes() == one.world_to_camera.tobytes()
        assert (cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height) == (one.fx, one.fy, one.cx, one.cy, 32, 24)
    # yaw pi/2 looks along +Y: 2 m ahead at camera height is 2 m deep on the optical axis
    w2c = agent_cameras(poses[2:, [0, 1, 3]], floor_z=0.1, camera_height=1.25)[0].world_to_camera
    np.testing.assert_allclose(w2c @ [-0.5, 2.25, 1.35, 1.0], [0.0, 0.0, 2.0, 1.0], atol=1e-12)
