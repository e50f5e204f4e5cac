"""The replay model of a built run's scene: the agent inside RUN/scenes/<scene_id>/scene.xml."""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import mujoco

from sagebench.errors import DataError
from sagebench.replay.physics import ReplayModel, build_replay_model
from sagebench.run_layout import MJCF, REPLAY_MODEL, SCENE_FILE, SEMANTIC_MAP, require, run_scene_dir
from sagebench.scene.loader import parse_spec
from sagebench.settings.shared import ReplayConfig
from sagebench.topdown.semantic_map import read_semantic_map


def floor_body_names(scene_dir: Path, bodies: Iterable[str]) -> list[str]:
    """Those of the MJCF `bodies` that are the scene's floor objects. export-usd names an object's body
    `<category>_<instance_id>` (as its USD prim, the category made a valid identifier), so a floor's body is the one
    whose name ends in `_<instance_id>`: found without usd-core, which a replay needs nowhere else."""
    spec_path = scene_dir / SCENE_FILE
    spec = parse_spec(spec_path.read_text(encoding="utf-8"), spec_path)
    floors = {str(o.instance_id) for o in spec.objects if o.kind == "floor"}
    return [b for b in bodies if "_" in b and b.rpartition("_")[2] in floors]


def open_replay_model(run_dir: Path, scene_id: str, *, replay: ReplayConfig) -> ReplayModel:
    """The replay agent in RUN/scenes/<scene_id>/scene.xml, floors not colliding (validate, evaluate, baseline);
    its body is the one the scene's map was built for (semantic_map.json)."""
    scene_dir = run_scene_dir(run_dir, scene_id)
    require(REPLAY_MODEL, run_dir, scene_id)
    agent = read_semantic_map(scene_dir / SEMANTIC_MAP).agent()
    spec_path = scene_dir / SCENE_FILE
    floor_z = parse_spec(spec_path.read_text(encoding="utf-8"), spec_path).floor_height
    try:
        mjspec = mujoco.MjSpec.from_file(str(scene_dir / MJCF))
    except ValueError as err:
        raise DataError(f"cannot load: {err}", path=scene_dir / MJCF) from None
    try:  # compiling reads the collider STLs: a deleted or corrupted one fails here
        return build_replay_model(mjspec, agent=agent, floor_z=floor_z, config=replay,
                                  floor_bodies=floor_body_names(scene_dir, [b.name for b in mjspec.bodies]))
    except ValueError as err:
        raise DataError(f"cannot compile: {err}", path=scene_dir / MJCF) from None
