"""The replay model of a built run's scene: the agent inside RUN/scenes/<scene_id>/scene.xml."""

from __future__ import annotations

from pathlib import Path

import mujoco

from sagebench.config import AgentConfig
from sagebench.errors import DataError
from sagebench.replay.physics import ReplayConfig, ReplayModel, build_replay_model
from sagebench.scene.loader import SCENE_FILE, parse_spec

MJCF_FILE = "scene.xml"


def floor_body_names(scene_dir: Path) -> list[str]:
    """MJCF bodies of the scene's floor objects (export-usd names bodies `<category>_<instance_id>`)."""
    from pxr import Tf

    spec_path = scene_dir / SCENE_FILE
    spec = parse_spec(spec_path.read_text(encoding="utf-8"), spec_path)
    return [Tf.MakeValidIdentifier(f"{o.category}_{o.instance_id}") for o in spec.objects if o.kind == "floor"]


def open_replay_model(run_dir: Path, scene_id: str, *, agent: AgentConfig, replay: ReplayConfig) -> ReplayModel:
    """The replay agent in RUN/scenes/<scene_id>/scene.xml, floors not colliding (validate, evaluate, baseline)."""
    scene_dir = Path(run_dir) / "scenes" / scene_id
    for name, stage in ((SCENE_FILE, "build-scene"), (MJCF_FILE, "export-usd")):
        if not (scene_dir / name).is_file():
            raise DataError(f"missing; run `sagebench {stage}` on this run first", path=scene_dir / name)
    spec_path = scene_dir / SCENE_FILE
    floor_z = parse_spec(spec_path.read_text(encoding="utf-8"), spec_path).floor_height
    try:
        mjspec = mujoco.MjSpec.from_file(str(scene_dir / MJCF_FILE))
    except ValueError as err:
        raise DataError(f"cannot load: {err}", path=scene_dir / MJCF_FILE) from None
    present = {b.name for b in mjspec.bodies}
    return build_replay_model(mjspec, agent=agent, floor_z=floor_z, config=replay,
                              floor_bodies=[n for n in floor_body_names(scene_dir) if n in present])
