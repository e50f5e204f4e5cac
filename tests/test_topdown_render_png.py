"""topdown.png: a readable picture whose colours mean what the legend says."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from sagebench.scene.loader import load_scene
from sagebench.topdown.builder import BuildSceneConfig, compute_topdown
from sagebench.topdown.render_png import DOOR, NAVIGABLE, UNREACHABLE, WALL, render_topdown


@pytest.fixture(scope="module")
def picture(demo_scene_dir):
    td = compute_topdown(load_scene(demo_scene_dir), BuildSceneConfig())
    data = render_topdown(td)
    img = cv2.cvtColor(cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    return td, data, img


def _has(img: np.ndarray, rgb) -> int:
    return int((img == np.array(rgb, np.uint8)).all(axis=2).sum())


def test_picture_is_scaled_map_plus_legend(picture):
    td, data, img = picture
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    h, w = td.grid.shape
    scale = round(1000 / max(h, w))
    assert img.shape[0] >= h * scale and img.shape[1] > w * scale


def test_walls_doors_by_state_and_legend_swatches_are_drawn(picture):
    _, _, img = picture
    assert _has(img, WALL) > 1000
    for state in ("open", "ajar", "closed"):
        assert _has(img, DOOR[state]) > 10, state
    # the navigable tint is blended over the floor, so the pure colour only appears as a legend swatch
    assert _has(img, NAVIGABLE) >= 12 * 12


def test_same_maps_give_the_same_bytes(picture):
    """Drawn again from the same maps (build-scene's own determinism: test_topdown_build_scene.py)."""
    td, data, _ = picture
    assert render_topdown(td) == data


def test_floor_outside_the_main_region_has_its_own_colour_and_legend_entry():
    """The concave house's office, behind an ajar door too narrow for a 0.25 m agent (its own region): every one
    of its navigable cells is drawn in the unreachable tint, the main region's in the navigable one."""
    from pathlib import Path

    from sagebench.settings.shared import AgentConfig

    house = Path(__file__).parent / "fixtures" / "concave_house"
    td = compute_topdown(load_scene(house), BuildSceneConfig(agent=AgentConfig(radius=0.25)))
    img = cv2.cvtColor(cv2.imdecode(np.frombuffer(render_topdown(td), np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    h, w = td.grid.shape
    scale = int(np.clip(round(1000 / max(h, w)), 2, 8))
    cells = img[30:30 + h * scale:scale, :w * scale:scale][::-1].astype(int)  # one pixel per cell, row 0 = lowest y
    away = td.navigable.astype(bool) & (td.region != td.semantic.main_region)
    main = td.navigable.astype(bool) & (td.region == td.semantic.main_region)
    assert away.sum() > 100 and main.sum() > 1000
    # blended over the background: more red than green off the main region, the reverse on it
    assert (cells[away][:, 0] > cells[away][:, 1]).all() and (cells[main][:, 1] > cells[main][:, 0]).all()
    assert _has(img, UNREACHABLE) >= 12 * 12  # the legend swatch
