"""Sweet Home 3D catalogues: entries parsed, models in metres Z-up at catalogue size, a demo furnished with them."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest
import trimesh

from sagebench.errors import SceneError
from sagebench.scene.furniture import CATALOGUE_FILE, Catalogue
from sagebench.scene.loader import load_scene
from sagebench.scene.synth import write_synth_scene

FIXTURE = Path(__file__).parent / "fixtures" / "sh3d_cc0"

# a 2 x 4 x 6 box (Y up) with one extra vertex at the front (+Z), width 20 cm, depth 60 cm, height 40 cm
BOX_OBJ = """v -1 0 -3\nv 1 0 -3\nv 1 4 -3\nv -1 4 -3\nv -1 0 3\nv 1 0 3\nv 1 4 3\nv -1 4 3\nv 0 2 3
f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\nf 4 1 5\nf 4 5 8\nf 5 9 6
"""
PROPS = "id#3=test#box\nname#3=Little box table\nmodel#3=/m/box.obj\nwidth#3=20\ndepth#3=60\nheight#3=40\n"


def _catalogue(root: Path, props: str = PROPS) -> Path:
    (root / "m").mkdir(parents=True)
    (root / "m" / "box.obj").write_text(BOX_OBJ)
    (root / CATALOGUE_FILE).write_text(props)
    return root


def test_fixture_catalogue_entries():
    cat = Catalogue(FIXTURE)
    assert [e.number for e in cat.entries] == [112, 114, 115, 134, 144, 149, 172, 173]
    chair = cat.entries[1]
    assert (chair.name, chair.model, chair.size_m, chair.creator) == (
        "Chair", "blendswap-cc-0/chair2/chair2.obj", pytest.approx((0.403, 0.489, 0.868), rel=1e-12), "Ingoenius")
    assert [e.number for e in cat.matching("chair")] == [114]
    assert [e.number for e in cat.matching("counter")] == [144, 172, 173]  # "Drawers cabinet", "Upper (corner) cabinet"
    assert cat.matching("bathtub") == []


@pytest.mark.parametrize("zipped", [False, True])
def test_model_is_z_up_metres_at_catalogue_size_front_to_minus_y(tmp_path, zipped):
    root = _catalogue(tmp_path / "cat")
    if zipped:
        with zipfile.ZipFile(tmp_path / "cat.sh3f", "w") as z:
            for p in root.rglob("*"):
                z.write(p, p.relative_to(root).as_posix())
        root = tmp_path / "cat.sh3f"
    cat = Catalogue(root)
    mesh = cat.load_model(cat.entries[0])
    np.testing.assert_allclose(mesh.bounds, [[-0.1, -0.3, 0.0], [0.1, 0.3, 0.4]], atol=1e-12)
    # the vertex at the model's front (+Z, half height) lands at -Y, z = 0.2
    assert np.min(np.linalg.norm(mesh.vertices - [0.0, -0.3, 0.2], axis=1)) < 1e-12


def test_bad_catalogues_name_the_file_and_key(tmp_path):
    with pytest.raises(SceneError, match=f"no {CATALOGUE_FILE}"):
        Catalogue(tmp_path)
    root = _catalogue(tmp_path / "c", PROPS.replace("depth#3=60", "depth#3=wide"))
    with pytest.raises(SceneError, match=r"depth#3: depth is missing or not a number"):
        Catalogue(root)
    root = _catalogue(tmp_path / "e", PROPS + "elevation#3=high\n")
    with pytest.raises(SceneError, match=r"elevation#3: elevation is not a number"):
        Catalogue(root)


def test_fixture_elevations_are_parsed_in_metres():
    cat = Catalogue(FIXTURE)
    assert {e.id.split("#")[1]: e.elevation_m for e in cat.entries if e.elevation_m} == \
        {"upperCabinet": pytest.approx(1.45), "upperCornerCabinet": pytest.approx(1.45)}


@pytest.mark.parametrize("seed", [0, 1])
def test_furnished_demo_keeps_the_layout_with_the_catalogue_sizes_as_sweet_home_3d(tmp_path, seed):
    """Each model at its catalogue width, depth and height (within 2 %: not shrunk to its slot) standing at its
    catalogue elevation; a model wider or deeper than its slot by more than a quarter is not used there."""
    write_synth_scene(tmp_path / "plain", seed=seed)
    write_synth_scene(tmp_path / "real", seed=seed, furniture=FIXTURE)
    plain, real = load_scene(tmp_path / "plain"), load_scene(tmp_path / "real")
    assert [(o.instance_id, o.category, o.transform.translation[:2], o.transform.rotation_wxyz)
            for o in plain.spec.objects] == \
        [(o.instance_id, o.category, o.transform.translation[:2], o.transform.rotation_wxyz) for o in real.spec.objects]
    models = {e.id: e for e in Catalogue(FIXTURE).entries}
    used = [o for o in real.spec.objects if "asset" in o.attributes]
    names = {o.attributes["asset"].split("#")[1] for o in used}
    assert {"chair2", "dustbin", "JapaneseLantern", "couch2"} <= names  # (the 2.35 m table fits no slot)
    assert "table" not in names
    for o in used:
        entry = models[o.attributes["asset"]]
        size = np.ptp(trimesh.load(tmp_path / "real" / o.mesh, force="mesh").vertices, axis=0)
        np.testing.assert_allclose(size, entry.size_m, rtol=0.02)
        slot = plain.object(o.instance_id)
        assert real.meshes[o.instance_id].bounds[0, 2] == pytest.approx(slot.transform.translation[2] + entry.elevation_m,
                                                                          abs=1e-6)


def test_a_wall_cabinet_hangs_at_its_catalogue_elevation(tmp_path):
    """The fixture's upper cabinet (elevation 145 cm) as the only cabinet: seed 1's counter hangs 1.45 m up."""
    import sagebench.scene.synth as synth

    cat = Catalogue(FIXTURE)
    cat.entries = [e for e in cat.entries if e.id.endswith("#upperCabinet")]
    spec, files = synth.synth_spec_and_meshes(1, cat)
    (counter,) = [o for o in spec.objects if o.attributes.get("asset") == "Blend Swap CC-0#upperCabinet"]
    assert counter.transform.translation[2] == pytest.approx(1.45)
    mesh = trimesh.load(trimesh.util.wrap_as_stream(files[counter.mesh]), file_type="glb", force="mesh")
    np.testing.assert_allclose(np.ptp(mesh.vertices, axis=0), (0.60, 0.41, 0.72), rtol=0.02)
    assert mesh.bounds[0, 2] == pytest.approx(0.0, abs=1e-9)  # the model stands on its own z = 0


def test_cli_bad_furniture_dir_writes_nothing(run_cli, tmp_path):
    furniture = tmp_path / "furniture"  # beside OUT: an OUT inside --furniture is refused before it is read
    furniture.mkdir()
    code, out, err = run_cli("synth-scene", "--out", tmp_path / "s", "--furniture", furniture)
    assert code == 2
    assert err.strip().splitlines() == [f"error: {furniture}: no {CATALOGUE_FILE} (expected a Sweet Home 3D catalogue directory or .sh3f)"]
    assert not (tmp_path / "s").exists()
