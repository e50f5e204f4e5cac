"""The committed JSON Schemas in schemas/ are exactly what the models generate."""

from pathlib import Path

from sagebench.schemas import render_schemas

SCHEMA_DIR = Path(__file__).resolve().parents[1] / "schemas"


def test_committed_schemas_are_current():
    stale = [name for name, data in render_schemas().items()
             if not (SCHEMA_DIR / name).is_file() or (SCHEMA_DIR / name).read_bytes() != data]
    assert not stale, f"run `make schemas` and commit: stale or missing {stale}"


def test_every_json_schema_declares_draft_2020_12_and_an_id():
    import json

    names = [n for n in render_schemas() if n.endswith(".json")]
    assert len(names) == 5
    ids = set()
    for name in names:
        schema = json.loads((SCHEMA_DIR / name).read_text())
        assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema", name
        assert schema["$id"].startswith("urn:sagebench:schemas:") and schema["$id"] not in ids
        ids.add(schema["$id"])


def test_arrow_schema_file_reads_back_as_the_episode_schema_with_descriptions():
    import pyarrow as pa

    from sagebench.episodes.schema import EPISODE_SCHEMA

    with pa.memory_map(str(SCHEMA_DIR / "episode.arrow")) as source:
        schema = pa.ipc.read_schema(source)
    assert schema.equals(EPISODE_SCHEMA, check_metadata=True)
    assert schema.field("goal_radius").metadata[b"description"] == b"Success radius around goal_position, metres."


def test_scene_schema_names_the_input_contract():
    import json

    schema = json.loads(render_schemas()["scene.schema.json"])
    obj = schema["$defs"]["SceneObject"]["properties"]
    assert set(schema["$defs"]["SceneObject"]["required"]) == {"instance_id", "category", "mesh"}
    assert obj["kind"]["enum"] == ["object", "wall", "floor", "ceiling", "door", "window"]
    assert schema["$defs"]["Door"]["properties"]["state"]["enum"] == ["open", "closed", "ajar"]
