"""Renderer backends: which one `auto`, `cpu` and `gsplat` pick, the CPU backend's frames unchanged, and the gsplat
backend's plumbing (one call for every view, frames back) with gsplat's math in numpy standing in for its kernel."""

from __future__ import annotations

import contextlib
import types

import numpy as np
import pytest

from sagebench.errors import ConfigError
from sagebench.render import backends
from sagebench.render.backends import CpuRenderer, GsplatRenderer, choose_backend, open_renderer
from sagebench.render.camera import agent_camera
from sagebench.render.chunks import pack
from sagebench.render.splat_render import render, render_packed
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


def _fake_torch():
    return types.SimpleNamespace(
        float32=np.float32, no_grad=contextlib.nullcontext,
        from_numpy=lambda a: np.asarray(a).view(_Tensor),
        tensor=lambda v, dtype, device: np.asarray(v, dtype=dtype).view(_Tensor))


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
