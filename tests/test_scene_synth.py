"""The demo apartment keeps the promises later stages rely on: rooms, categories, no overlaps, a walkable floor."""

from __future__ import annotations

import hashlib
import itertools
from collections import Counter
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy import ndimage
from shapely.geometry import MultiPoint

from sagebench.scene.assets import NON_BLOCKING
from sagebench.scene.loader import load_scene
from sagebench.scene.synth import write_synth_scene

ROBOT_R = 0.2
CELL = 0.05


def _digest(scene_dir: Path) -> dict[str, str]:
    return {str(p.relative_to(scene_dir)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(scene_dir.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def demo(demo_scene_dir):
    return load_scene(demo_scene_dir)


def test_same_seed_gives_byte_identical_files(demo_scene_dir, tmp_path):
    write_synth_scene(tmp_path / "again", seed=0)
    assert _digest(tmp_path / "again") == _digest(demo_scene_dir)


def test_different_seeds_give_different_layouts(demo, tmp_path):
    write_synth_scene(tmp_path / "s1", seed=1)
    other = load_scene(tmp_path / "s1")
    a = sorted(tuple(np.round(m.bounds.ravel(), 2)) for m in demo.meshes.values())
    b = sorted(tuple(np.round(m.bounds.ravel(), 2)) for m in other.meshes.values())
    assert a != b


def test_rooms_and_size(demo):
    types = [r.type for r in demo.spec.rooms]
    assert len(types) >= 4 and len(set(types)) == len(types)
    assert {"kitchen", "living_room", "bedroom", "bathroom"} <= set(types)
    assert len(demo.spec.objects) >= 40


def test_furniture_categories_and_attribute_twins(demo):
    furniture = [o for o in demo.spec.objects if o.kind == "object"]
    cats = Counter(o.category for o in furniture)
    assert len(cats) >= 15
    assert all({"colour", "material"} <= o.attributes.keys() for o in furniture)
    # some category has several instances that differ in colour (so "the red chair" means something)
    assert any(len({o.attributes["colour"] for o in furniture if o.category == c}) > 1 for c, n in cats.items() if n > 1)


def test_door_states_across_seeds(demo, tmp_path):
    states = {o.door.state for o in demo.spec.objects if o.door}
    assert states == {"open", "ajar", "closed"}


def test_meshes_are_not_just_boxes(demo):
    by_cat = {demo.object(i).category: m for i, m in demo.meshes.items()}
    table = by_cat["coffee_table"]
    hull_area = MultiPoint(table.vertices[:, :2]).convex_hull.area
    low = table.vertices[table.vertices[:, 2] < 0.3][:, :2]  # only the legs reach below the top
    assert len(low) and MultiPoint(low).convex_hull.area == pytest.approx(hull_area, rel=0.2)
    assert table.volume < 0.3 * table.bounding_box.volume
    assert by_cat["ceiling_lamp"].bounds[0, 2] > 1.2
    assert by_cat["rug"].extents[2] <= 0.02
    sofa = by_cat["sofa"]
    assert sofa.volume < 0.8 * sofa.bounding_box_oriented.volume  # L-shaped, not a block


def _blocking(demo):
    for iid, mesh in demo.meshes.items():
        obj = demo.object(iid)
        if obj.kind in ("floor", "ceiling", "window") or obj.category in NON_BLOCKING:
            continue
        yield obj, mesh


def test_furniture_footprints_do_not_overlap(demo):
    hulls = [(o, MultiPoint(m.vertices[:, :2]).convex_hull) for o, m in _blocking(demo) if o.kind == "object"]
    for (a, ha), (b, hb) in itertools.combinations(hulls, 2):
        if {a.category, b.category} == {"tv", "tv_stand"}:
            continue  # the tv stands on its stand
        assert ha.intersection(hb).area < 1e-6, (a.category, a.instance_id, b.category, b.instance_id)


def test_floor_is_connected_for_the_robot(demo):
    """Rasterise everything in the robot's height band as posed (doors included), inflate by the robot
    radius, and check that one free region reaches into every room."""
    lo = np.min([m.bounds[0] for m in demo.meshes.values()], axis=0)[:2] - 0.5
    hi = np.max([m.bounds[1] for m in demo.meshes.values()], axis=0)[:2] + 0.5
    shape = tuple(np.ceil((hi - lo) / CELL).astype(int))[::-1]
    blocked = np.zeros(shape, np.uint8)
    for _, mesh in _blocking(demo):
        tri = mesh.triangles
        in_band = (tri[:, :, 2].min(axis=1) < 1.2) & (tri[:, :, 2].max(axis=1) > 0.05)
        for t in tri[in_band]:
            pix = np.round((t[:, :2] - lo) / CELL * 8).astype(np.int32)
            cv2.fillPoly(blocked, [pix], 1, lineType=cv2.LINE_8, shift=3)
    free = np.zeros(shape, bool)
    for room in demo.spec.rooms:
        pix = np.round((np.array(room.polygon) - lo) / CELL * 8).astype(np.int32)
        mask = np.zeros(shape, np.uint8)
        cv2.fillPoly(mask, [pix], 1, shift=3)
        free |= mask.astype(bool)
    free = ndimage.binary_dilation(free, iterations=4) & ~blocked.astype(bool)  # reach into door openings
    walk = ndimage.distance_transform_edt(free) * CELL > ROBOT_R
    labels, _ = ndimage.label(walk)
    main = np.bincount(labels.ravel())[1:].argmax() + 1
    for room in demo.spec.rooms:
        pix = np.round((np.array(room.polygon) - lo) / CELL * 8).astype(np.int32)
        mask = np.zeros(shape, np.uint8)
        cv2.fillPoly(mask, [pix], 1, shift=3)
        assert (labels[mask.astype(bool)] == main).sum() * CELL**2 > 2.0, room.type
