"""Paths drawn over a scene's topdown.png as SVG: the picture stays one file per scene, each page adds only its
lines, and a scene page can hide the paths a filter leaves out. Points land where topdown.png draws them
(render_png.map_pixels at its map_scale, below its title strip)."""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sagebench.errors import DataError
from sagebench.report.html import CONTACT, GOAL, START, esc
from sagebench.topdown.grid_file import TopdownGrids
from sagebench.topdown.render_png import MAP_TOP, map_pixels, map_scale


PAD, FIT, ZOOM = 40.0, 640.0, 3.0  # an episode's part of the map: margin, size shown and largest enlargement, px


@dataclass(frozen=True)
class MapFrame:
    """Where a scene's points fall on its topdown.png (pixels), and the picture's size."""

    grids: TopdownGrids
    width: int
    height: int

    @property
    def scale(self) -> int:
        return map_scale(*self.grids.navigable.shape)

    def pixels(self, xy: np.ndarray) -> np.ndarray:
        g = self.grids
        return map_pixels(np.asarray(xy, dtype=np.float64)[:, :2], g.navigable.shape[0], self.scale, g.resolution,
                          g.origin, MAP_TOP)

    def points(self, xy: np.ndarray) -> str:
        """An SVG points attribute of the world (x, y) rows of `xy`."""
        return " ".join(f"{x:.1f},{y:.1f}" for x, y in self.pixels(xy))

    def metres(self, m: float) -> float:
        return m / self.grids.resolution * self.scale


def map_frame(png: Path, grids: TopdownGrids) -> MapFrame:
    """The frame of a topdown.png (its size read from its PNG header)."""
    head = png.read_bytes()[:24]
    if head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR":
        raise DataError("not a PNG: run build-scene again", path=png)
    width, height = struct.unpack(">II", head[16:24])
    return MapFrame(grids, int(width), int(height))


def marker(frame: MapFrame, xy: Sequence[float], kind: str, radius_m: float | None = None) -> str:
    """A start dot, a goal dot with its radius ring (`radius_m`), or a contact cross."""
    (x, y), = frame.pixels(np.asarray([xy[:2]]))
    if kind == "start":
        return f'<circle class="start" cx="{x:.1f}" cy="{y:.1f}" r="5" fill="{START}"/>'
    if kind == "goal":
        ring = "" if radius_m is None else (f'<circle class="goal-radius" cx="{x:.1f}" cy="{y:.1f}" '
                                            f'r="{frame.metres(radius_m):.1f}" fill="none" stroke="{GOAL}"/>')
        return ring + f'<circle class="goal" cx="{x:.1f}" cy="{y:.1f}" r="4" fill="{GOAL}"/>'
    return (f'<path class="contact" d="M{x - 4:.1f},{y - 4:.1f}L{x + 4:.1f},{y + 4:.1f}M{x - 4:.1f},{y + 4:.1f}'
            f'L{x + 4:.1f},{y - 4:.1f}" stroke="{CONTACT}" stroke-width="2"/>')


def svg_map(frame: MapFrame, href: str, items: Sequence[str], *, around: np.ndarray | None = None,
            title: str = "", cls: str = "map") -> str:
    """The map picture with `items` (SVG elements) over it; with `around` (pixel points), only the part of the
    map around them, enlarged up to ZOOM times to about FIT pixels."""
    x0, y0, w, h, zoom = 0.0, 0.0, float(frame.width), float(frame.height), 1.0
    if around is not None and len(around):
        lo = np.maximum(around.min(axis=0) - PAD, 0.0)
        hi = np.minimum(around.max(axis=0) + PAD, [frame.width, frame.height])
        x0, y0, w, h = float(lo[0]), float(lo[1]), float(hi[0] - lo[0]), float(hi[1] - lo[1])
        zoom = float(np.clip(FIT / max(w, h), 1.0, ZOOM))
    label = f' aria-label="{esc(title)}"' if title else ""
    return (f'<svg class="{cls}" viewBox="{x0:.0f} {y0:.0f} {w:.0f} {h:.0f}" width="{w * zoom:.0f}" '
            f'height="{h * zoom:.0f}" role="img"{label}>\n'
            f'<image href="{esc(href)}" x="0" y="0" width="{frame.width}" height="{frame.height}"/>\n'
            + "\n".join(items) + "\n</svg>")
