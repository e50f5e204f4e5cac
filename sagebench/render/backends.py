"""Renderer backends behind one interface: the CPU splat renderer (the reference) and gsplat on a CUDA GPU.

A caller opens a renderer for one scene's Gaussians (`open_renderer`) and hands it every view it needs at once:
`observe(cams, keys)` gives what an agent sees, the batch as arrays (render/observations.py: uint8 RGB, masked
depth, alpha, instance ids), converted where the frames are (on the GPU for gsplat) and copied back once;
`render(cams)` gives the float frames (the render stage, the GPU check's agreement). `auto` takes gsplat when a CUDA device,
torch and gsplat (`pip install 'sagebench[gpu]'`) are present and gsplat draws every image asked for, else the
CPU renderer. gsplat builds its CUDA kernels on first use (about a minute) into the user cache directory, once.
"""

from __future__ import annotations

import importlib.util
import os
import sys
from collections.abc import Collection, Sequence
from importlib import metadata
from pathlib import Path
from typing import Protocol

import numpy as np

from sagebench import ui
from sagebench.errors import ConfigError
from sagebench.render.camera import Camera
from sagebench.render.chunks import PackedGaussians
from sagebench.render.gaussians import Gaussians
from sagebench.render.observations import fields_for, observation_arrays
from sagebench.render.splat_reference import Frame

CHOICES: tuple[str, ...] = ("auto", "cpu", "gsplat")
Background = tuple[float, float, float]


class Renderer(Protocol):
    name: str  # the backend: cpu or gsplat
    draws: frozenset[str]  # the images it draws, of rgb, depth, alpha, instance

    def render(self, cams: Sequence[Camera]) -> list[Frame]:
        """One frame per camera (all of one image size for gsplat); `instance` is None where the backend draws
        no instance ids."""
        ...

    def observe(self, cams: Sequence[Camera], keys: Collection[str]) -> dict[str, np.ndarray]:
        """The images `keys` of every camera (at least one, all of one size) as [C, H, W(, 3)] arrays
        (render/observations.py). The arrays are the caller's: no later call writes into them."""
        ...


class CpuRenderer:
    """The CPU splat renderer (splat_render): packed Gaussians are culled by chunk, frames render side by side."""

    name = "cpu"
    draws = frozenset({"rgb", "depth", "alpha", "instance"})

    def __init__(self, gaussians: Gaussians | PackedGaussians, background: Background = (0.0, 0.0, 0.0),
                 real: type = np.float32):
        """`real`: the frames' precision, float32, or float64 for the reference frames (splat_render.REFERENCE)."""
        self.gaussians, self.background, self.real = gaussians, background, real

    def render(self, cams: Sequence[Camera], ids: bool = True) -> list[Frame]:
        """Without `ids`, the frames' instance is None and the ids are not drawn (an observation without them)."""
        from sagebench.render.splat_render import render, render_packed

        if isinstance(self.gaussians, PackedGaussians):
            return render_packed(self.gaussians, cams, background=self.background, real=self.real, ids=ids)
        return [render(self.gaussians, cam, background=self.background, real=self.real, ids=ids) for cam in cams]

    def observe(self, cams: Sequence[Camera], keys: Collection[str]) -> dict[str, np.ndarray]:
        fields = fields_for(keys)
        frames = self.render(_checked(cams, keys, self), ids="instance" in fields)
        return observation_arrays({f: np.stack([getattr(fr, f) for fr in frames]) for f in fields}, keys)


class GsplatRenderer:
    """gsplat's `rasterization` on a CUDA device: the Gaussians stay on the device, one call renders every view."""

    name = "gsplat"
    draws = frozenset({"rgb", "depth", "alpha"})

    def __init__(self, gaussians: Gaussians | PackedGaussians, background: Background = (0.0, 0.0, 0.0), *,
                 device: str = "cuda"):
        from sagebench.render.gsplat_convention import scene_arrays

        self._torch, self._rasterization = load_gsplat()
        g = gaussians.gaussians if isinstance(gaussians, PackedGaussians) else gaussians
        s = scene_arrays(g)
        put = lambda a: self._torch.from_numpy(a).to(device)  # noqa: E731
        self._scene = {"means": put(s.means), "quats": put(s.quats), "scales": put(s.scales),
                       "opacities": put(s.opacities), "colors": put(s.colors)}
        self._sh_degree, self._device = s.sh_degree, device
        self._background = self._torch.tensor(background, dtype=self._torch.float32, device=device)

    def render(self, cams: Sequence[Camera]) -> list[Frame]:
        from sagebench.render.gsplat_convention import frames_from_gsplat

        if not cams:
            return []
        colors, alphas = self.rasterize(cams)
        return frames_from_gsplat(colors.cpu().numpy(), alphas.cpu().numpy())

    def observe(self, cams: Sequence[Camera], keys: Collection[str]) -> dict[str, np.ndarray]:
        """Converted on the device, then each array copied once into page-locked host memory (a fast DMA copy)
        that becomes the caller's: torch's caching host allocator hands a block out again only after the caller
        has let go of every array in it (a frame kept alone keeps its whole batch's block)."""
        colors, alphas = self.rasterize(_checked(cams, keys, self))
        torch = self._torch
        with torch.no_grad():
            fields = {"rgb": colors[..., :3], "depth": colors[..., 3], "alpha": alphas[..., 0]}
            device = observation_arrays(fields, keys, torch)
            host = {k: torch.empty(a.shape, dtype=a.dtype, pin_memory=True) for k, a in device.items()}
            for k, a in device.items():
                host[k].copy_(a, non_blocking=True)
            torch.cuda.current_stream().synchronize()
        return {k: h.numpy() for k, h in host.items()}

    def rasterize(self, cams: Sequence[Camera]):
        """gsplat's output on the device: colors [C, H, W, 4] (RGB + expected depth) and alphas [C, H, W, 1]."""
        from sagebench.render.gsplat_convention import camera_arrays, raster_settings

        c = camera_arrays(cams)
        torch = self._torch
        with torch.no_grad():
            colors, alphas, _ = self._rasterization(
                **self._scene, viewmats=torch.from_numpy(c.viewmats).to(self._device),
                Ks=torch.from_numpy(c.Ks).to(self._device), width=c.width, height=c.height,
                sh_degree=self._sh_degree, backgrounds=self._background.expand(len(cams), 3), packed=False,
                **raster_settings())
        return colors, alphas


def _checked(cams: Sequence[Camera], keys: Collection[str], renderer: Renderer) -> Sequence[Camera]:
    """The cameras of one `observe` call, checked: at least one, one image size, images the backend draws."""
    if not cams:
        raise ValueError("no cameras to observe from")
    sizes = {(c.width, c.height) for c in cams}
    if len(sizes) > 1:
        raise ValueError(f"one observe call takes cameras of one image size, got {sorted(sizes)}")
    lacking = sorted(set(fields_for(keys)) - renderer.draws)
    if lacking:
        raise ValueError(f"the {renderer.name} renderer draws no {lacking[0]} images")
    return cams


def gsplat_missing() -> str | None:
    """Why gsplat cannot render here, or None when it can (torch and gsplat installed, a CUDA device seen)."""
    for module in ("torch", "gsplat"):
        if importlib.util.find_spec(module) is None:
            return f"{module} is not installed (pip install 'sagebench[gpu]')"
    import torch

    if not torch.cuda.is_available():
        return "torch sees no CUDA device"
    return None


def choose_backend(choice: str, needs: Collection[str]) -> str:
    """The backend that renders `needs` (image names: rgb, depth, alpha, instance) for `choice` (auto, cpu or
    gsplat); an explicit gsplat that cannot draw them or cannot run here is a ConfigError naming --renderer."""
    if choice not in CHOICES:
        raise ConfigError(f"{choice!r} is not one of {', '.join(CHOICES)}", field="--renderer")
    lacking = sorted(set(needs) - GsplatRenderer.draws)
    if choice == "cpu":
        return "cpu"
    if choice == "auto":
        return "gsplat" if not lacking and gsplat_missing() is None else "cpu"
    if lacking:
        raise ConfigError(f"the gsplat renderer draws no {lacking[0]} images; use --renderer cpu or auto",
                          field="--renderer")
    why = gsplat_missing()
    if why:
        raise ConfigError(f"the gsplat renderer cannot run here: {why}", field="--renderer")
    return "gsplat"


def open_renderer(gaussians: Gaussians | PackedGaussians, choice: str = "cpu", *, needs: Collection[str] = ("rgb",),
                  background: Background = (0.0, 0.0, 0.0)) -> Renderer:
    """A renderer of these Gaussians by the backend `choose_backend(choice, needs)` picks."""
    if choose_backend(choice, needs) == "gsplat":
        return GsplatRenderer(gaussians, background)
    return CpuRenderer(gaussians, background)


def extensions_dir() -> Path:
    """Where gsplat's CUDA build is cached: the user cache directory, one folder per Python, torch and gsplat
    version (torch's TORCH_EXTENSIONS_DIR holds builds by name only)."""
    import platformdirs

    tag = f"py{sys.version_info.major}{sys.version_info.minor}-torch{metadata.version('torch')}-" \
          f"gsplat{metadata.version('gsplat')}"
    return Path(platformdirs.user_cache_dir("sagebench")) / "torch_extensions" / tag


def load_gsplat():
    """(torch, gsplat.rasterization), gsplat's CUDA kernels built (saying so first) or loaded from the cache."""
    why = gsplat_missing()
    if why:
        raise ConfigError(f"the gsplat renderer cannot run here: {why}", field="--renderer")
    os.environ.setdefault("TORCH_EXTENSIONS_DIR", str(extensions_dir()))
    build = Path(os.environ["TORCH_EXTENSIONS_DIR"]) / "gsplat_cuda"
    if not any(build.glob("gsplat_cuda.*")):
        ui.info(f"gsplat: compiling its CUDA kernels, once (about a minute); cached in {build}")
    import torch
    from gsplat import rasterization
    from gsplat.cuda._backend import _C

    if _C is None:
        raise ConfigError("gsplat could not build its CUDA kernels: no CUDA toolkit (nvcc) found",
                          field="--renderer")
    return torch, rasterization
