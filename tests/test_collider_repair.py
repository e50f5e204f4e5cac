"""Hole closing before CoACD: closed pieces untouched, an open box closed to its volume."""

from __future__ import annotations

import numpy as np
import trimesh

from sagebench.collider_export.repair import close_holes, is_closed


def test_a_closed_piece_is_returned_as_it_is():
    box = trimesh.creation.box((0.4, 0.3, 0.5))
    v, f = close_holes(box.vertices, box.faces)
    assert np.array_equal(v, box.vertices) and np.array_equal(f, box.faces)


def test_an_open_box_is_closed_to_its_volume():
    box = trimesh.creation.box((0.4, 0.3, 0.5))
    v, f = box.vertices, box.faces[2:]  # one side missing
    assert not is_closed(v, f)
    rv, rf = close_holes(v, f)
    assert is_closed(rv, rf)
    assert abs(abs(trimesh.Trimesh(rv, rf).volume) - 0.06) < 1e-9
