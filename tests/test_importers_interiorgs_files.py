"""Reading an InteriorGS folder: both labels.json forms, the occupancy image's orientation, and the compressed
PLY as PlayCanvas writes it (tests/interiorgs_fixture.py) read back within its quantisation."""

from __future__ import annotations

import json
import math
import shutil

import cv2
import numpy as np
import pytest

from interiorgs_fixture import compressed_ply, inria_ply, morton_order
from sagebench.errors import DataError
from sagebench.importers.interiorgs_files import is_interiorgs_folder, read_folder, read_labels, read_occupancy
from sagebench.render.gaussians import SH_C0, Gaussians
from sagebench.splats.ply import read_ply


def test_labels_as_a_list_or_under_a_key(tmp_path):
    box = [{"x": x, "y": y, "z": z} for z in (0, 1) for x, y in ((0, 0), (1, 0), (1, 2), (0, 2))]
    items = [{"ins_id": 17, "label": " Chair ", "bounding_box": box, "extra": "kept out"}]
    (tmp_path / "a.json").write_text(json.dumps(items))
    (tmp_path / "b.json").write_text(json.dumps({"labels": items}))
    for name in ("a.json", "b.json"):
        (label,) = read_labels(tmp_path / name)
        assert (label.index, label.ins_id, label.label) == (0, "17", "Chair")
        assert label.corners.shape == (8, 3)
    items[0]["bounding_box"][2]["y"] = "far"
    (tmp_path / "b.json").write_text(json.dumps({"labels": items}))
    with pytest.raises(DataError, match=r"b.json: labels\[0\].bounding_box\[2\].y: Input should be a valid number"):
        read_labels(tmp_path / "b.json")


def test_occupancy_png_is_the_grid_turned_by_180_degrees(tmp_path):
    """SAGE-3D's semantic map builder flips the image up-down only and draws boxes at (H-1-i, W-1-j): for the two
    to agree, image row r is y row r from `min` and image column c is x column W-1-c."""
    image = np.full((4, 6), 127, np.uint8)
    image[1, 4] = 255  # -> y row 1, x column 1
    cv2.imwrite(str(tmp_path / "occupancy.png"), image)
    (tmp_path / "occupancy.json").write_text(json.dumps({"scale": 0.5, "min": [10.0, 20.0, 0], "max": [13.0, 22.0, 3]}))
    occ = read_occupancy(tmp_path / "occupancy.png", tmp_path / "occupancy.json")
    assert np.argwhere(occ.free).tolist() == [[1, 1]]
    assert occ.origin == (10.0, 20.0) and occ.scale == 0.5  # that cell's centre: (10.75, 20.75)


def test_a_16_bit_occupancy_png_reads_as_its_8_bit_twin(tmp_path):
    """A 16-bit grey PNG (0, 32639, 65535) is the 8-bit map (0, 127, 255) scaled: unknown stays unknown, not free."""
    grid = np.array([[0, 127, 255], [255, 127, 0]], dtype=np.uint8)
    (tmp_path / "occupancy.json").write_text(json.dumps({"scale": 0.5, "min": [0.0, 0.0]}))
    cv2.imwrite(str(tmp_path / "eight.png"), grid)
    cv2.imwrite(str(tmp_path / "sixteen.png"), grid.astype(np.uint16) * 257)
    eight = read_occupancy(tmp_path / "eight.png", tmp_path / "occupancy.json")
    sixteen = read_occupancy(tmp_path / "sixteen.png", tmp_path / "occupancy.json")
    assert sixteen.values.dtype == np.uint8 and np.array_equal(sixteen.values, eight.values)
    assert sixteen.free.sum() == 2


def test_a_folder_is_told_apart_from_a_scene(interiorgs_demo, demo_scene_dir, tmp_path):
    assert is_interiorgs_folder(interiorgs_demo[0])
    assert not is_interiorgs_folder(demo_scene_dir)
    shutil.copytree(interiorgs_demo[0], tmp_path / "f", ignore=shutil.ignore_patterns("*.ply"))
    with pytest.raises(DataError, match=r"f: missing 3dgs_compressed.ply \(an InteriorGS scene folder holds"):
        read_folder(tmp_path / "f")
    folder = read_folder(interiorgs_demo[0])
    assert folder.scene_id == "0001_839920" and len(folder.rooms) == 5 and len(folder.walls) == 16


def _gaussians(n: int, degree: int, seed: int = 0) -> Gaussians:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4)).astype(np.float32)
    return Gaussians(rng.uniform(-5, 5, (n, 3)).astype(np.float32), q, rng.uniform(-5, -2, (n, 3)).astype(np.float32),
                     rng.normal(size=n).astype(np.float32),
                     rng.uniform(-1, 1, (n, (degree + 1) ** 2, 3)).astype(np.float32), np.zeros(n, np.int32))


@pytest.mark.parametrize("degree", [0, 3])
def test_compressed_layout_reads_back_within_its_quantisation(tmp_path, degree):
    g = _gaussians(1000, degree)
    g = g.take(morton_order(g.means))
    (tmp_path / "c.ply").write_bytes(compressed_ply(g))
    back = read_ply(tmp_path / "c.ply")
    pad = np.concatenate([np.arange(1000), np.full(24, 999)])  # 4 chunks of 256, the last filled up
    span = np.ptp(g.means[pad].reshape(4, 256, 3), axis=1)[np.arange(1000) // 256]  # [N, 3] its chunk's range
    half_step = span / (2 * np.array([2047, 1023, 2047]))  # 11, 10 and 11 bits
    assert (np.abs(back.means - g.means) <= half_step + 1e-5).all()
    scale_span = np.ptp(g.log_scales[pad].reshape(4, 256, 3), axis=1)[np.arange(1000) // 256]
    assert (np.abs(back.log_scales - g.log_scales) <= scale_span / (2 * np.array([2047, 1023, 2047])) + 1e-5).all()
    unit = g.quats_wxyz / np.linalg.norm(g.quats_wxyz, axis=1, keepdims=True)
    same = np.abs((back.quats_wxyz * unit).sum(axis=1))  # q and -q are one rotation
    assert same.min() > 1 - 1e-5 and np.allclose(np.linalg.norm(back.quats_wxyz, axis=1), 1, atol=1e-3)
    rgb, rgb_back = g.sh[:, 0] * SH_C0 + 0.5, back.sh[:, 0] * SH_C0 + 0.5
    assert np.abs(rgb_back - rgb).max() <= np.ptp(rgb, axis=0).max() / 255 / 2 + 1e-6
    alpha = 1 / (1 + np.exp(-g.opacity_logits))
    assert np.abs(1 / (1 + np.exp(-back.opacity_logits)) - alpha).max() <= 0.5 / 255 + 1e-6
    assert back.sh_degree == degree
    if degree:
        assert np.abs(back.sh[:, 1:] - g.sh[:, 1:]).max() <= 8 / 256 + 1e-6


def test_inria_layout_without_ids_reads_back_exactly(tmp_path):
    g = _gaussians(50, 1)
    (tmp_path / "g.ply").write_bytes(inria_ply(g))
    back = read_ply(tmp_path / "g.ply")
    assert np.array_equal(back.means, g.means) and np.array_equal(back.sh, g.sh)
    assert not back.instance_id.any()
    assert math.isfinite(float(back.opacity_logits.sum()))
