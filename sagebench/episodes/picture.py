"""One episode as a picture: the plain map, the reference path, the agent's path with the steps where it touched
something, start, goal and goal radius, the instruction as a caption and the episode's metrics beneath.

Drawn with OpenCV's Hershey fonts (ASCII; other letters are simplified or shown as '?'), so the same episode
gives the same bytes. The map keeps paths.png's colours and pixel grid (`plain_map`, `map_pixels`).
"""

from __future__ import annotations

import textwrap
import unicodedata
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from sagebench.episodes.episode import Episode
from sagebench.episodes.preview import GOAL, START, plain_map, png_bytes
from sagebench.topdown.grid_file import TopdownGrids
from sagebench.topdown.render_png import map_pixels

REFERENCE, AGENT, CONTACT, STOP = (31, 119, 180), (255, 127, 14), (214, 39, 40), (120, 60, 0)  # RGB
HEADER_PX = 28  # the title line above the map; the map starts this many pixels down
MIN_WIDTH = 640  # narrower maps get white margins on the right, so the caption has room
LINE_PX = 20
MAX_CAPTION_LINES = 5
FONT = cv2.FONT_HERSHEY_SIMPLEX
TEXT_SCALE = 0.5
PNG_LEVEL = 6  # a third of OpenCV's default size for a few ms more


@dataclass(frozen=True)
class AgentPath:
    poses: np.ndarray  # [T, 4] x, y, z, yaw
    contact: np.ndarray | None  # [T] c(t), None when unknown


def scale_for(shape: tuple[int, int], max_size_px: int) -> int:
    """Pixels per cell so that the longer side of the map is at most `max_size_px` (at least 1)."""
    return max(1, max_size_px // max(shape))


def episode_picture(grid: TopdownGrids, episode: Episode, agent: AgentPath | None, title: str, caption: str,
                    notes: Sequence[str], *, max_size_px: int = 720, base: np.ndarray | None = None) -> bytes:
    """PNG bytes of one episode (module docstring). `base` is `plain_map` of the grid at this size, when the
    caller draws many episodes of one scene; `notes` are the lines under the caption (the metrics)."""
    h, w = grid.navigable.shape
    scale = scale_for((h, w), max_size_px)
    if base is None:
        base = plain_map(grid.navigable, grid.occupancy, scale)

    def px(xy: np.ndarray) -> np.ndarray:
        return np.round(map_pixels(xy, h, scale, grid.resolution, grid.origin, HEADER_PX)).astype(np.int32)

    caption_lines = _wrapped(caption, max(base.shape[1], MIN_WIDTH) - 16)
    height = HEADER_PX + base.shape[0] + LINE_PX * (2 + len(caption_lines) + len(notes)) + 6
    img = np.full((height, max(base.shape[1], MIN_WIDTH), 3), 255, np.uint8)
    img[HEADER_PX:HEADER_PX + base.shape[0], :base.shape[1]] = base
    thick = max(2, scale)
    cv2.polylines(img, [px(episode.reference_path[:, :2])], False, REFERENCE, thick, cv2.LINE_AA)
    if agent is not None:
        _draw_agent(img, px(agent.poses[:, :2]), agent.contact, thick)
    goal, start = px(episode.goal[None, :2])[0], px(episode.start[None, :2])[0]
    radius = max(1, int(round(episode.goal_radius / grid.resolution * scale)))
    cv2.circle(img, tuple(map(int, goal)), radius, GOAL, 1, cv2.LINE_AA)
    cv2.circle(img, tuple(map(int, goal)), thick + 1, GOAL, -1, cv2.LINE_AA)
    cv2.circle(img, tuple(map(int, start)), thick + 2, START, -1, cv2.LINE_AA)
    _text(img, _ascii(title), (8, 19))
    y = HEADER_PX + base.shape[0] + LINE_PX
    _legend(img, y, agent is not None)
    for k, line in enumerate([*caption_lines, *(_ascii(n) for n in notes)]):
        _text(img, line, (8, y + LINE_PX * (k + 1)))
    return png_bytes(img, PNG_LEVEL)


def _draw_agent(img: np.ndarray, px: np.ndarray, contact: np.ndarray | None, thick: int) -> None:
    """The agent's path, a cross at every step with contact (c(t) > 0) and a ring where it ended."""
    cv2.polylines(img, [px], False, AGENT, max(1, thick - 1), cv2.LINE_AA)
    if contact is not None:
        for x, y in px[np.asarray(contact) > 0]:
            cv2.drawMarker(img, (int(x), int(y)), CONTACT, cv2.MARKER_TILTED_CROSS, 4 * thick, 2, cv2.LINE_AA)
    cv2.circle(img, tuple(map(int, px[-1])), thick + 3, STOP, 2, cv2.LINE_AA)


def _legend(img: np.ndarray, y: int, with_agent: bool) -> None:
    items = [("start", START), ("goal, its radius", GOAL), ("reference path", REFERENCE)]
    if with_agent:
        items += [("agent", AGENT), ("contact", CONTACT), ("agent stopped", STOP)]
    x = 8
    for name, colour in items:
        cv2.rectangle(img, (x, y - 10), (x + 12, y + 2), colour, -1)
        x += 18
        _text(img, name, (x, y))
        x += _width(name) + 14


def _text(img: np.ndarray, text: str, at: tuple[int, int]) -> None:
    cv2.putText(img, text, at, FONT, TEXT_SCALE, (0, 0, 0), 1, cv2.LINE_AA)


def _width(text: str) -> int:
    return cv2.getTextSize(text, FONT, TEXT_SCALE, 1)[0][0]


def _ascii(text: str) -> str:
    """What the Hershey font can draw: accents dropped, other non-ASCII letters as '?'."""
    plain = unicodedata.normalize("NFKD", text)
    plain = "".join(c for c in plain if not unicodedata.combining(c))
    return plain.encode("ascii", "replace").decode("ascii")


def _wrapped(text: str, width_px: int) -> list[str]:
    """`text` in lines that fit `width_px`, at most MAX_CAPTION_LINES (the last ends in '...' when cut)."""
    text = _ascii(" ".join(text.split()))
    chars = max(10, width_px * 26 // _width("abcdefghijklmnopqrstuvwxyz"))
    lines = textwrap.wrap(text, chars)
    while chars > 10 and any(_width(line) > width_px for line in lines):
        chars -= 2
        lines = textwrap.wrap(text, chars)
    if len(lines) > MAX_CAPTION_LINES:
        lines = [*lines[:MAX_CAPTION_LINES - 1], lines[MAX_CAPTION_LINES - 1][:-3] + "..."]
    return lines
