"""JSON Schemas of every file format sagebench reads or writes, generated from the models, and the episode
row's Arrow schemas as IPC files (a vln run's, and a run's with other tasks). Every JSON Schema declares its dialect ($schema, draft 2020-12) and an
$id naming it."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from sagebench.fileio import dumps_json


def _scene_schema() -> dict[str, Any]:
    from sagebench.scene.model import SceneSpec

    return SceneSpec.model_json_schema()


def _semantic_map_schema() -> dict[str, Any]:
    from sagebench.topdown.semantic_map import SemanticMap

    return SemanticMap.model_json_schema()


def _run_config_schema() -> dict[str, Any]:
    from sagebench.settings.run import RunConfig

    return RunConfig.model_json_schema(by_alias=True)


def _predictions_schema() -> dict[str, Any]:
    from sagebench.evaluation.predictions import Prediction

    return Prediction.model_json_schema()


def _rollout_record_schema() -> dict[str, Any]:
    from sagebench.evaluation.record import RolloutRecord

    return RolloutRecord.model_json_schema()


# file name in schemas/ -> function returning the schema; later stages add their formats here.
SCHEMAS: dict[str, Callable[[], dict[str, Any]]] = {
    "scene.schema.json": _scene_schema,
    "semantic_map.schema.json": _semantic_map_schema,
    "run_config.schema.json": _run_config_schema,
    "predictions.schema.json": _predictions_schema,
    "rollout_record.schema.json": _rollout_record_schema,
}


DIALECT = "https://json-schema.org/draft/2020-12/schema"
EPISODE_ARROW = "episode.arrow"  # the episode row's Arrow schema (IPC), with each column's description
EPISODE_TASKS_ARROW = "episode_tasks.arrow"  # the same once a task other than vln is written (episodes/tasks.py)


def schema_id(name: str) -> str:
    """The $id of schemas/<name>: a URN, since the schemas have no web home."""
    return f"urn:sagebench:schemas:{name}"


def render_schemas() -> dict[str, bytes]:
    """file name -> contents: canonical JSON text of each JSON Schema, the IPC bytes of the Arrow schema."""
    from sagebench.episodes.schema import episode_schema_ipc
    from sagebench.episodes.tasks import TASK_SCHEMA

    out = {name: dumps_json({"$schema": DIALECT, "$id": schema_id(name), **make()}).encode()
           for name, make in sorted(SCHEMAS.items())}
    out[EPISODE_ARROW] = episode_schema_ipc()
    out[EPISODE_TASKS_ARROW] = episode_schema_ipc(TASK_SCHEMA)
    return dict(sorted(out.items()))


def write_schemas(out: Path) -> list[Path]:
    from sagebench.fileio import write_bytes
    from sagebench.run_folder import check_place

    check_place(out, "schemas", folder=True)  # never into a run
    written = []
    for name, data in render_schemas().items():
        write_bytes(out / name, data)
        written.append(out / name)
    return written
