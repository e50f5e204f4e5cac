"""JSON Schemas of every file format sagebench reads or writes, generated from the models."""

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


def _episode_schema() -> dict[str, Any]:
    from sagebench.episodes.schema import episode_schema_json

    return episode_schema_json()


def _run_config_schema() -> dict[str, Any]:
    from sagebench.pipeline.config import RunConfig

    return RunConfig.model_json_schema(by_alias=True)


def _predictions_schema() -> dict[str, Any]:
    from sagebench.evaluation.predictions import Prediction

    return Prediction.model_json_schema()


# file name in schemas/ -> function returning the schema; later stages add their formats here.
SCHEMAS: dict[str, Callable[[], dict[str, Any]]] = {
    "scene.schema.json": _scene_schema,
    "semantic_map.schema.json": _semantic_map_schema,
    "episode.arrow.json": _episode_schema,
    "run_config.schema.json": _run_config_schema,
    "predictions.schema.json": _predictions_schema,
}


def render_schemas() -> dict[str, str]:
    """file name -> canonical JSON text."""
    return {name: dumps_json(make()) for name, make in sorted(SCHEMAS.items())}


def write_schemas(out: Path) -> list[Path]:
    from sagebench.fileio import write_text

    written = []
    for name, text in render_schemas().items():
        write_text(out / name, text)
        written.append(out / name)
    return written
