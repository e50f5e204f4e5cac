"""The committed JSON Schemas in schemas/ are exactly what the models generate."""

from pathlib import Path

from sagebench.schemas import render_schemas

SCHEMA_DIR = Path(__file__).resolve().parents[1] / "schemas"


def test_committed_schemas_are_current():
    stale = [name for name, text in render_schemas().items()
             if not (SCHEMA_DIR / name).is_file() or (SCHEMA_DIR / name).read_text() != text]
    assert not stale, f"run `make schemas` and commit: stale or missing {stale}"


def test_scene_schema_names_the_input_contract():
    import json

    schema = json.loads(render_schemas()["scene.schema.json"])
    obj = schema["$defs"]["SceneObject"]["properties"]
    assert set(schema["$defs"]["SceneObject"]["required"]) == {"instance_id", "category", "mesh"}
    assert obj["kind"]["enum"] == ["object", "wall", "floor", "ceiling", "door", "window"]
    assert schema["$defs"]["Door"]["properties"]["state"]["enum"] == ["open", "closed", "ajar"]
