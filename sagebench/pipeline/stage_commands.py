"""The stage commands (build-scene, gen-trajectories, export-usd, validate, import-sage-episodes) leave the stamps
`sagebench run` leaves: a run made stage by stage is checked as one made by `run`, and `run` skips its stages
when the settings are the same.

Each command first checks, for every scene and before anything is written, the files it reads against the
stamps of the stages that wrote them (sagebench.stamps); then it runs the stage scene by scene, stamping each
scene's outputs as soon as they are in place.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

from pydantic import BaseModel

from sagebench import stamps
from sagebench.run_layout import run_scenes, stage_files

if TYPE_CHECKING:
    from sagebench.settings.build_scene import BuildSceneConfig
    from sagebench.settings.export_usd import ExportConfig
    from sagebench.settings.import_sage_episodes import SageImportConfig
    from sagebench.settings.validate import ValidateConfig
    from sagebench.stages.build_scene import BuildSceneResult
    from sagebench.stages.export_usd import ExportResult
    from sagebench.stages.gen_trajectories import GenTrajectoriesConfig, SceneEpisodes
    from sagebench.stages.import_sage import SageImport
    from sagebench.stages.validate import SceneValidation

R = TypeVar("R")


def _stamped(stage: str, run_dir: Path, scene_ids: list[str], config: BaseModel, work: Callable[[str], R],
             report: Callable[[R], tuple[str, bool]], check: Callable[[str], None] | None = None) -> Iterator[R]:
    """`work` on each scene (its result, whose summary line and verdict `report` gives), after `check` (by
    default: the files the stage reads as their writers' stamps record them) has passed for every scene. What
    is missing with no stamp to say so is the stage's to judge (export-usd goes on without gaussians.ply)."""
    for sid in scene_ids:
        (check or (lambda s: stamps.check_reads(stage, run_dir, s)))(sid)
    settings = config.model_dump(mode="json")
    for sid in scene_ids:
        key = stamps.stage_key(stage, settings, stage_files(stage, "reads", run_dir, sid), run_dir)
        result = work(sid)
        stamps.write_stamp(run_dir, sid, stage, key, *report(result))
        yield result


def build_scene(scene_dir: Path, run_dir: Path, config: BuildSceneConfig) -> BuildSceneResult:
    """stages.build_scene.build_scene, stamped (the key from SCENE_DIR's files, read before the build)."""
    from sagebench.stages.build_scene import build_scene

    reads = stage_files("build_scene", "reads", run_dir, "", scene_dir)  # the source scene's files: no scene id yet
    key = stamps.stage_key("build_scene", config.model_dump(mode="json"), reads, run_dir, scene_dir)
    result = build_scene(scene_dir, run_dir, config)
    stamps.write_stamp(run_dir, result.scene_id, "build_scene", key, result.summary(), True)
    return result


def gen_trajectories(run_dir: Path, config: GenTrajectoriesConfig, *, scene_id: str | None = None,
                     api_key: str | None = None) -> Iterator[SceneEpisodes]:
    from sagebench.stages.gen_trajectories import gen_trajectories

    return _stamped("gen_trajectories", run_dir, run_scenes(run_dir, scene_id), config,
                    lambda sid: gen_trajectories(run_dir, config, scene_id=sid, api_key=api_key)[0],
                    lambda r: (r.summary(), True))


def export_usd(run_dir: Path, config: ExportConfig, *, scene_id: str | None = None,
               cache_dir: Path | None = None) -> Iterator[ExportResult]:
    from sagebench.stages.export_usd import export_usd

    return _stamped("export_usd", run_dir, run_scenes(run_dir, scene_id), config,
                    lambda sid: export_usd(run_dir, scene_id=sid, config=config, cache_dir=cache_dir)[0],
                    lambda r: (r.line(), True))


def validate(run_dir: Path, config: ValidateConfig, *, scene_id: str | None = None) -> Iterator[SceneValidation]:
    """validate's own input checks (the manifest's files, else the stamps' files, and the USD stage) stand in
    for the default ones."""
    from sagebench.stages.validate import check_inputs, validate_scene

    return _stamped("validate", run_dir, run_scenes(run_dir, scene_id, having="episodes"), config,
                    lambda sid: validate_scene(run_dir, sid, config), lambda r: (r.summary(), r.passed),
                    check=lambda sid: check_inputs(run_dir, sid))


def import_sage_episodes(file: Path, run_dir: Path, config: SageImportConfig, *,
                         scene_id: str | None = None) -> SageImport:
    """The scene is known once the file is read: the stage checks its scene.json against build-scene's stamp
    itself, and the key (of scene.json and FILE, which the import does not change) is taken after it."""
    from sagebench.stages.import_sage import import_sage_episodes

    result = import_sage_episodes(file, run_dir, config, scene_id=scene_id)
    reads = [*stage_files("import_sage", "reads", run_dir, result.scene_id), Path(file)]
    key = stamps.stage_key("import_sage", config.model_dump(mode="json"), reads, run_dir, Path(file).parent)
    stamps.write_stamp(run_dir, result.scene_id, "import_sage", key, "\n".join(result.lines()), True)
    return result
