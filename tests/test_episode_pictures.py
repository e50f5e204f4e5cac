"""An episode's picture (evaluate --visualize): every path and marker lands where the map puts its world point,
contact is marked exactly at the steps with c(t) > 0, and the same episode gives the same bytes."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from sagebench.episodes.episode import Episode
from sagebench.episodes.picture import AGENT, CONTACT, HEADER_PX, REFERENCE, AgentPath, episode_picture
from sagebench.episodes.preview import GOAL, NAVIGABLE, START
from sagebench.topdown.grid_file import TopdownGrids

# a 4 x 2 m open floor at 0.05 m cells, origin (0, 0): 80 x 40 cells, drawn 720 // 80 = 9 px per cell
GRID = TopdownGrids(np.ones((40, 80), np.uint8), np.zeros((40, 80), np.uint8), 0.05, (0.0, 0.0))
SCALE = 9
EPISODE = Episode("e1", "room", "low", "Base_Action", start=np.array([0.5, 1.0, 0.0]), start_yaw=0.0,
                  goal=np.array([2.5, 1.0, 0.0]), goal_radius=0.5, geodesic_distance=2.0,
                  reference_path=np.array([[0.5, 1.0, 0.0, 0.0], [2.5, 1.0, 0.0, 0.0]]))
# the agent steps north, then east along y = 1.5 m, touching something at its third pose (1.5, 1.5)
POSES = np.array([[0.5, 1.0, 0, 0], [0.5, 1.5, 0, 0], [1.5, 1.5, 0, 0], [2.5, 1.5, 0, 0]], dtype=np.float64)


def pixel(x: float, y: float) -> tuple[int, int]:
    """(row, column) of world (x, y): column x / 0.05 * 9, row (40 - y / 0.05) * 9 below the title line."""
    return int(round((40 - y / 0.05) * SCALE)) + HEADER_PX, int(round(x / 0.05 * SCALE))


def draw(contact=(0.0, 0.0, 0.5, 0.0)) -> tuple[bytes, np.ndarray]:
    png = episode_picture(GRID, EPISODE, AgentPath(POSES, np.array(contact)), "room  e1", "Walk east 2 m.",
                          ["SR 1"])
    return png, cv2.cvtColor(cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)


def test_a_known_path_lands_on_known_pixels():
    _, img = draw()
    assert tuple(img[pixel(1.5, 1.0)]) == REFERENCE and tuple(img[pixel(0.75, 1.0)]) == REFERENCE
    assert tuple(img[pixel(1.0, 1.5)]) == AGENT and tuple(img[pixel(0.5, 1.25)]) == AGENT  # north up: y 1.5 above 1
    assert tuple(img[pixel(1.5, 1.5)]) == CONTACT  # the step with c(t) = 0.5
    assert tuple(img[pixel(0.5, 1.0)]) == START and tuple(img[pixel(2.5, 1.0)]) == GOAL
    ring = img[pixel(3.0, 1.0)]  # 0.5 m east of the goal: its radius, drawn to scale
    assert ring[0] > 200 and ring[1] < 80 and ring[2] < 80
    assert tuple(img[pixel(3.25, 1.0)]) == (NAVIGABLE,) * 3 and tuple(img[pixel(1.5, 0.5)]) == (NAVIGABLE,) * 3


def test_contact_is_marked_only_where_c_is_above_zero():
    _, img = draw(contact=(0.0, 0.0, 0.0, 0.0))
    assert tuple(img[pixel(1.5, 1.5)]) == AGENT
    assert not (img == np.array(CONTACT, np.uint8)).all(axis=2)[HEADER_PX:HEADER_PX + 40 * SCALE].any()
    _, img = draw(contact=(0.0, 0.3, 0.0, 0.0))  # the second pose, (0.5, 1.5)
    assert tuple(img[pixel(0.5, 1.5)]) == CONTACT and tuple(img[pixel(1.5, 1.5)]) == AGENT


def test_the_same_episode_gives_the_same_bytes():
    a, _ = draw()
    assert draw()[0] == a and a[:8] == b"\x89PNG\r\n\x1a\n"
    assert draw(contact=(0.0, 0.0, 0.0, 0.0))[0] != a


@pytest.mark.parametrize("caption", ["Gehe zur Küche, dann links — bis zum Sofa.", "word " * 200, ""])
def test_any_instruction_is_drawn_below_the_map(caption):
    png = episode_picture(GRID, EPISODE, None, "room  e1", caption, ["no prediction"])
    img = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    assert img.shape[1] == 720 and img.shape[0] <= HEADER_PX + 40 * SCALE + 20 * 9  # at most five caption lines
    assert png == episode_picture(GRID, EPISODE, None, "room  e1", caption, ["no prediction"])
