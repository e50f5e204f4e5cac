"""The `sagebench` command: parses options, calls one library function per command, prints.

Every SagebenchError becomes one line on stderr and exit status 2, here and nowhere else.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated

import typer
import typer.core

from sagebench.cli_settings import given, settings, settings_command
from sagebench.errors import ConfigError, Interrupted, OutputError, SagebenchError
from sagebench.ui import SETTINGS, interrupted, interrupts_noted

app = typer.Typer(
    add_completion=True,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,  # click's plain help: rewrapped to the terminal (80 columns at most), flags without a value
    help="Turn artist-made indoor scenes into a physically executable VLN benchmark.",
)


def existing(path: Path | list[Path] | None) -> Path | list[Path] | None:
    """The callback of every input path a command reads (its arguments, --run, --config, --predictions,
    --furniture; each path of an option given many times): one that does not exist, or is a FIFO or device (a read
    that would block or never end), is the error, before anything else runs or is written."""
    from sagebench.input_files import special_kind

    for p in path if isinstance(path, list) else [path]:
        if p is not None and not p.exists():
            raise ConfigError("does not exist", path=p)
        kind = None if p is None else special_kind(p)
        if kind is not None:
            raise ConfigError(f"is {kind}, not a file or folder: sagebench reads inputs from regular files only", path=p)
    return path


def splits(incomplete: str) -> list[str]:
    """Shell completion of --split: the benchmark's splits."""
    from sagebench.settings.shared import SPLITS

    return [s for s in SPLITS if s.startswith(incomplete)]


GLOBAL_FLAGS = ("--quiet", "-q", "--debug")  # accepted before or after the command
Force = Annotated[bool, typer.Option(
    "--force", help="Write into a folder that also holds files other than a sagebench run's; they are never changed "
                    "(one where the command writes still refuses it).")]

ForceFile = Annotated[bool, typer.Option(
    "--force", help="Replace an existing OUT (or a file written beside it) that sagebench did not write; never one "
                    "in a sagebench run or an input.")]


def _show_version(value: bool) -> None:
    if value:
        from sagebench import __version__

        typer.echo(f"sagebench {__version__}")
        raise typer.Exit()


@app.callback()
def _global(
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Hide progress bars and progress lines.")] = False,
    debug: Annotated[bool, typer.Option("--debug", help="Show the full traceback on errors.")] = False,
    version: Annotated[bool, typer.Option("--version", callback=_show_version, is_eager=True,
                                          help="Print the version and exit.")] = False,
) -> None:
    SETTINGS.quiet = quiet
    SETTINGS.debug = debug


def hoist_global_flags(argv: list[str]) -> list[str]:
    """`sagebench CMD ... --quiet` as `sagebench --quiet CMD ...`: the global flags may follow the command
    (not after a `--`)."""
    end = argv.index("--") if "--" in argv else len(argv)
    flags = [a for a in argv[:end] if a in GLOBAL_FLAGS]
    return flags + [a for a in argv[:end] if a not in GLOBAL_FLAGS] + argv[end:]


@app.command("synth-scene")
def synth_scene(
    out: Annotated[Path, typer.Option("--out", help="Scene directory to create: absent, empty or an earlier "
                                                     "synth scene (replaced whole).")],
    seed: Annotated[int, typer.Option(help="Layout seed; the same seed gives byte-identical files.")] = 0,
    furniture: Annotated[Path | None, typer.Option(
        callback=existing, help="Sweet Home 3D furniture catalogue (directory or .sh3f) whose models replace the procedural pieces.")] = None,
    force: Annotated[bool, typer.Option("--force", help="Replace OUT whatever it holds, unless it is FURNITURE, "
                                                        "lies inside it or holds it.")] = False,
) -> None:
    """Write a procedural apartment in the artist-scene input format.

    Reads FURNITURE/PluginFurnitureCatalog.properties and its OBJ/MTL models when given. Writes
    OUT/scene.json and OUT/meshes/*.glb|.ply|.obj; refuses an OUT that is a file or a directory holding
    anything but an earlier synth scene, unless --force, and, even with --force, an OUT that is FURNITURE,
    lies inside it or holds it, or lies inside a sagebench run.
    """
    from sagebench.run_folder import check_scene_out
    from sagebench.scene.synth import is_synth_scene, write_synth_scene

    check_scene_out(out, "synth-scene", ours=is_synth_scene, force=force, inputs={"--furniture": furniture})
    spec = write_synth_scene(out, seed=seed, furniture=furniture, force=force)
    typer.echo(f"wrote {out} ({len(spec.rooms)} rooms, {len(spec.objects)} objects)")


@app.command("check-scene")
def check_scene(
    scene_dir: Annotated[Path, typer.Argument(
        metavar="SCENE_DIR", callback=existing, help="Artist scene directory (scene.json + meshes) or InteriorGS scene folder.")],
) -> None:
    """Check a scene directory as build-scene would (same checks, default settings) and print a summary.

    Reads SCENE_DIR/scene.json, every mesh it names and its trained gaussians.ply if any (an InteriorGS folder
    is imported in memory first). Writes nothing.
    """
    from sagebench.scene.summary import summarise
    from sagebench.stages.build_scene import check_scene

    checked = check_scene(scene_dir)
    h, w = checked.grid.shape
    trained = "none" if checked.trained is None else f"{checked.trained.count} Gaussians"
    typer.echo(summarise(checked.scene) + f"\nmap: at most {w}x{h} cells at {checked.grid.resolution:g} m; "
               f"trained gaussians.ply: {trained}")


@app.command("schemas")
def schemas(
    out: Annotated[Path, typer.Option("--out", help="Directory for the *.schema.json files.")] = Path("schemas"),
) -> None:
    """Regenerate the JSON Schemas of sagebench's file formats.

    Reads nothing. Writes OUT/*.schema.json.
    """
    from sagebench.schemas import write_schemas

    for path in write_schemas(out):
        typer.echo(f"wrote {path}")


@app.command("demo")
def demo(
    out: Annotated[Path, typer.Option("--out", help="Run directory for the demo.")] = Path("out/demo"),
    seed: Annotated[int, typer.Option(help="Seed of the demo scene and of every stage.")] = 0,
    force: Force = False,
) -> None:
    """Generate the built-in demo scene and run the whole pipeline on it.

    Reads nothing. Writes OUT/input/demo_apartment_<seed>/ (the scene), OUT/run.toml (its run config, so
    `sagebench run OUT/run.toml` and `sagebench verify OUT --regenerate --config OUT/run.toml` work),
    the run layout under OUT (scenes/, episodes/, validation/, manifest.json) and the oracle baseline's
    predictions and scores (OUT/baselines/oracle.jsonl, oracle_results.json).
    """
    from sagebench.pipeline.demo import run_demo

    result = run_demo(out, seed=seed, force=force)
    summary = result.run
    for line in summary.lines():
        typer.echo(line)
    if result.scores:
        typer.echo("oracle baseline scores (sagebench evaluate):\n" + result.scores)
    typer.echo(f"results are in {out}/ (top-down maps: {out}/scenes/*/topdown.png, paths: "
               f"{out}/previews/*/paths.png, frames: {out}/reports/*/frames/)")
    if not summary.ok:
        raise typer.Exit(1)


@app.command("import-interiorgs", cls=settings_command("sagebench.settings.import_interiorgs:InteriorGSConfig"))
def import_interiorgs_cmd(
    ctx: typer.Context,
    src: Annotated[Path, typer.Argument(
        metavar="SRC", callback=existing, help="InteriorGS scene folder (3dgs_compressed.ply, labels.json, structure.json, "
                                "occupancy.png, occupancy.json).")],
    out: Annotated[Path, typer.Option("--out", help="Scene directory to create: absent, empty or an earlier import "
                                                     "(replaced whole).")],
    collision_usd: Annotated[Path | None, typer.Option(
        "--collision-usd", callback=existing,
        help="SAGE-3D's collision USD for this scene: its meshes replace the surfaces made from Gaussians for the "
             "objects they match.")] = None,
    force: Annotated[bool, typer.Option("--force", help="Replace OUT whatever it holds, unless it is SRC or "
                                                        "COLLISION_USD, lies inside one or holds one.")] = False,
) -> None:
    """Turn an InteriorGS scene folder (3D Gaussians and labels, no meshes) into a sagebench scene.

    Reads SRC/3dgs_compressed.ply (SuperSplat's compressed layout; or 3dgs.ply in the INRIA layout),
    labels.json, structure.json, occupancy.png and occupancy.json, and COLLISION_USD when given.

    Writes OUT/scene.json, OUT/meshes/*.ply (walls with their openings, floor and ceiling slabs, and each
    object's surface made from its own Gaussians), OUT/gaussians.ply (the Gaussians with instance ids),
    OUT/interiorgs_import.json (shares of Gaussians per outcome, floaters dropped, the surface noise, doors,
    unlabelled obstacles, the occupancy agreement) and OUT/occupancy_check.png (occupancy.png against the
    imported geometry, the unlabelled obstacles in orange). Geometry no label explains (background Gaussians dense in the agent's band,
    cells occupancy.png marks occupied) becomes "unlabelled" obstacles, a warning past max_unlabelled_area m^2.
    OUT must be new, empty or an
    earlier import (unless --force), and never SRC or COLLISION_USD, inside one, a folder holding one, or
    inside a sagebench run. build-scene and run also take SRC directly.
    """
    from sagebench.stages.import_interiorgs import import_interiorgs_scene

    config = settings(ctx)
    typer.echo(import_interiorgs_scene(src, out, config, collision_usd=collision_usd, force=force).summary())


@app.command("build-scene", cls=settings_command("sagebench.settings.build_scene:BuildSceneConfig"))
def build_scene_cmd(
    ctx: typer.Context,
    scene_dir: Annotated[Path, typer.Argument(
        metavar="SCENE_DIR", callback=existing, help="Artist scene directory (scene.json + meshes) or InteriorGS scene folder.")],
    out: Annotated[Path, typer.Option("--out", help="Run directory; writes OUT/scenes/<scene_id>/.")],
    force: Force = False,
) -> None:
    """Build the semantic top-down map, the height-band occupancy and the Gaussians of one scene.

    Reads SCENE_DIR/scene.json and its meshes, or an InteriorGS scene folder (imported as
    import-interiorgs does, with default settings).

    Writes OUT/scenes/<scene_id>/: scene.json and meshes/ (normalised), topdown.npz,
    semantic_map.json, topdown.png and gaussians.ply (the scene's trained gaussians.ply with
    instance ids, else Gaussians sampled on every mesh).

    --agent-radius, --band-min and --band-max declare the agent's body; semantic_map.json records it,
    and export-usd's collider band check, validate, evaluate and the env take it from there.

    With --prune it prints the held-out PSNR of the pruned against the unpruned Gaussians. OUT must be new,
    empty or a sagebench run (unless --force), and is locked while it is written. The stamp
    OUT/.stamps/<scene_id>/build_scene.json records every file written with its sha256; later stages check
    what they read against it.
    """
    from sagebench.pipeline.stage_commands import build_scene
    from sagebench.run_folder import check_scenes_apart, claim_run_dir

    config = settings(ctx)
    check_scenes_apart(out, [scene_dir])
    with claim_run_dir(out, "build-scene", force=force):
        typer.echo(build_scene(scene_dir, out, config).summary())


@app.command("gen-trajectories", cls=settings_command("sagebench.settings.gen_trajectories:GenTrajectoriesConfig",
                                                     before="--llm-api-key-env"))
def gen_trajectories_cmd(
    ctx: typer.Context,
    run_dir: Annotated[Path, typer.Argument(metavar="RUN_DIR", callback=existing, help="Run directory that build-scene wrote (RUN/scenes/<id>/).")],
    scene: Annotated[str | None, typer.Option("--scene", help="Only this scene id (default: every scene).")] = None,
    llm_api_key_env: Annotated[str | None, typer.Option(
        help="Name of the environment variable holding the LLM API key (default: SAGEBENCH_LLM_API_KEY).")] = None,
    force: Force = False,
) -> None:
    """Sample A* trajectories between objects and rooms and write them with low- and high-level instructions.

    Reads RUN_DIR/scenes/<id>/topdown.npz, semantic_map.json and scene.json. Writes
    RUN_DIR/episodes/<id>/part-<split>-NNNNN.parquet (one row per trajectory-instruction pair) and
    RUN_DIR/previews/<id>/paths.png. With --instructions llm it also reads and writes the
    answer cache; the API key comes from the environment variable SAGEBENCH_LLM_API_KEY (or the one
    --llm-api-key-env names). Exit status 1 when the LLM gave no usable answer for a scene.

    Refuses (exit 2, nothing written) a file it reads that differs from what build-scene's stamp records;
    writes its own stamp, RUN_DIR/.stamps/<id>/gen_trajectories.json.
    """
    import os

    from sagebench.errors import ConfigError, Interrupted
    from sagebench.instructions.llm_client import api_key_from_env
    from sagebench.pipeline.stage_commands import gen_trajectories
    from sagebench.run_folder import claim_run_dir
    from sagebench.stages.gen_trajectories import make_config

    config = make_config(given(ctx))
    api_key = None
    if llm_api_key_env is not None:
        if config.instructions != "llm":
            raise ConfigError("used only with --instructions llm", field="--llm-api-key-env")
        api_key = api_key_from_env(llm_api_key_env, os.environ)
    try:
        with claim_run_dir(run_dir, "gen-trajectories", force=force):
            for result in gen_trajectories(run_dir, config, scene_id=scene, api_key=api_key):
                typer.echo(result.summary())
    except KeyboardInterrupt:  # click would print "Aborted!" and exit 1
        raise Interrupted("interrupted: the scene in progress was not written") from None


@app.command("render", cls=settings_command("sagebench.settings.render:RenderConfig", before="--depth-out"))
def render_cmd(
    ctx: typer.Context,
    run_dir: Annotated[Path, typer.Argument(metavar="RUN_DIR", callback=existing, help="Run directory with scenes/<scene_id>/ from build-scene.")],
    scene: Annotated[str, typer.Option("--scene", help="Scene id (a directory under RUN_DIR/scenes).")],
    pose: Annotated[str, typer.Option("--pose", help="X,Y,YAW: camera position on the floor, m, and heading, rad.")],
    out: Annotated[Path, typer.Option("--out", help="PNG file to write.")],
    depth_out: Annotated[Path | None, typer.Option("--depth-out", help="Also write depth, float32 .npy, m.")] = None,
    instance_out: Annotated[Path | None, typer.Option("--instance-out", help="Also write instance ids, int32 .npy.")] = None,
    force: ForceFile = False,
) -> None:
    """Render one view of a built scene's 3D Gaussians (on the CPU unless --renderer says otherwise).

    The camera stands at (X, Y, floor + camera height), looks along YAW (radians, counter-clockwise
    from +X), Z up, tilted by PITCH.

    Reads RUN_DIR/scenes/<scene>/scene.json and gaussians.ply.

    Writes OUT (PNG), and with --depth-out the expected z-depth (float32 .npy, metres, 0 where nothing
    was hit) and with --instance-out the instance id per pixel (int32 .npy, 0 = background); never inside a
    sagebench run, nor over a file sagebench did not write (unless --force).
    """
    from sagebench.stages.render import parse_pose, render_files

    config = settings(ctx)
    for path in render_files(run_dir, scene, parse_pose(pose), config, out, depth_out=depth_out,
                             instance_out=instance_out, force=force):
        typer.echo(f"wrote {path}")


@app.command("export-usd", cls=settings_command("sagebench.settings.export_usd:ExportConfig"))
def export_usd_cmd(
    ctx: typer.Context,
    run_dir: Annotated[Path, typer.Argument(metavar="RUN_DIR", callback=existing, help="Run directory that build-scene wrote (RUN/scenes/<id>/).")],
    scene: Annotated[str | None, typer.Option("--scene", help="Export only this scene id (default: every scene).")] = None,
    cache_dir: Annotated[
        Path | None, typer.Option("--cache-dir", help="Collider piece cache (default: the user cache directory).")
    ] = None,
    force: Force = False,
) -> None:
    """Decompose colliders and write each scene's USD stage and MuJoCo model.

    Reads RUN_DIR/scenes/<id>/scene.json, its meshes and gaussians.ply.

    Writes RUN_DIR/scenes/<id>/colliders/ (convex parts as STL + colliders.json with each object's
    collider quality), scene.usda (the stage's text root: semantics, physics) referencing geometry.usdc
    (binary: the 3D Gaussians and invisible collider meshes), scene.xml (MJCF) and with --usdz scene.usdz;
    with --gaussians nurec the Gaussians go to gaussians.usdz (NuRec) instead, and with --layout sage also
    sage/<id>.usda and sage/<id>_collision.usd. Each finished piece goes to the cache at once, so an
    interrupted export resumes there.

    Refuses (exit 2, nothing written) a file it reads that differs from what build-scene's stamp records;
    writes its own stamp, RUN_DIR/.stamps/<id>/export_usd.json.
    """
    from sagebench.pipeline.stage_commands import export_usd
    from sagebench.run_folder import claim_run_dir

    config = settings(ctx)
    with claim_run_dir(run_dir, "export-usd", force=force):
        for result in export_usd(run_dir, config, scene_id=scene, cache_dir=cache_dir):
            typer.echo(result.line())


@app.command("validate", cls=settings_command("sagebench.settings.validate:ValidateConfig"))
def validate_cmd(
    ctx: typer.Context,
    run_dir: Annotated[Path, typer.Argument(metavar="RUN_DIR", callback=existing, help="Run directory with scenes/<id>/ (build-scene, export-usd) and episodes/<id>/.")],
    scene: Annotated[str | None, typer.Option("--scene", help="Validate only this scene id (default: every scene).")] = None,
    force: Force = False,
) -> None:
    """Replay every trajectory in MuJoCo, score it and spot-check appearance against physics.

    Reads RUN_DIR/scenes/<id>/scene.json, scene.xml (+ colliders/), gaussians.ply and
    RUN_DIR/episodes/<id>/part-*.parquet.

    Writes RUN_DIR/validation/<id>/part-00000.parquet (one row per trajectory: pass/fail, reasons,
    CSR, ICP, PS, path length, steps, ...) and RUN_DIR/reports/<id>/: report.json (counts, failures by
    reason, metric distributions, alignment per frame) and frames/*.png with frames/contact_sheet.png.

    Refuses (exit 2, nothing written) a scene whose files differ from what RUN_DIR/manifest.json records or,
    in a run without a manifest, from what the stamps of the stages that wrote them record; writes its own
    stamp, RUN_DIR/.stamps/<id>/validate.json.

    Exit status 1 when any trajectory fails or a frame's depths disagree, listing the failures.
    """
    from sagebench.pipeline.stage_commands import validate
    from sagebench.run_folder import claim_run_dir

    config = settings(ctx)
    failed = False
    with claim_run_dir(run_dir, "validate", force=force):
        for result in validate(run_dir, config, scene_id=scene):
            typer.echo(result.summary())
            for trajectory_id, reasons in result.failures:
                typer.echo(f"  FAIL {result.scene_id} {trajectory_id}: {', '.join(reasons)}")
            for frame in result.frames:
                if frame.problem:
                    typer.echo(f"  FAIL {result.scene_id} {frame.file}: {frame.problem}")
            failed |= not result.passed
    if failed:
        raise typer.Exit(code=1)


@app.command("export-vlnce", cls=settings_command("sagebench.settings.export_vlnce:VlnceExportConfig"))
def export_vlnce_cmd(
    ctx: typer.Context,
    run_dir: Annotated[Path, typer.Argument(metavar="RUN_DIR", callback=existing, help="Run directory with episodes/<id>/ and scenes/<id>/.")],
    out: Annotated[Path, typer.Option("--out", help="Dataset directory to write (habitat's data_path root).")],
    split: Annotated[str | None, typer.Option("--split", autocompletion=splits,
                                              help="Export only this split (default: every split).")] = None,
) -> None:
    """Export the episodes as a VLN-CE / habitat R2R dataset, in habitat's Y-up frame.

    Reads RUN_DIR/episodes/<id>/part-*.parquet and RUN_DIR/scenes/<id>/scene.json + meshes/.

    Writes OUT/<split>/<split>.json.gz per split (episodes and instruction_vocab) with
    OUT/<split>/<split>_gt.json.gz (the oracle's teacher path: what VLN-CE's NDTW and recollect trainer
    read), OUT/vocab.txt, OUT/vlnce_opts.txt (the VLN-CE config options for this data, printed too: paths,
    splits, vocabulary size, success distance) and OUT/scenes/<id>/<id>.glb (the scene's visual meshes,
    Y up) for habitat-sim. instruction_tokens index the run's vocabulary, or the one given (--vocab: a pretrained
    VLN-CE model's), split by --tokenizer, as rollout's closed loop does. OUT must be new, empty or an earlier
    export-vlnce output, outside RUN_DIR.
    """
    from sagebench.run_folder import claim_export_dir
    from sagebench.stages.export_vlnce import OPTS_FILE, export_vlnce

    config = settings(ctx)
    with claim_export_dir(out, run_dir, "export-vlnce", OPTS_FILE):
        for line in export_vlnce(run_dir, out, split=split, config=config).lines():
            typer.echo(line)


@app.command("export-habitat")
def export_habitat_cmd(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN_DIR", callback=existing, help="Run directory with episodes/<id>/ and scenes/<id>/.")],
    out: Annotated[Path, typer.Option("--out", help="Directory for the datasets (habitat's data_path root).")],
    split: Annotated[str | None, typer.Option("--split", autocompletion=splits,
                                              help="Export only this split (default: every split).")] = None,
) -> None:
    """Export the ObjectNav, PointNav and ImageNav episodes as habitat-lab datasets of those tasks, Y up.

    ObjectNav as ObjectNav-v1 (goals_by_category, the category maps), PointNav and ImageNav as PointNav-v1 (what
    habitat-lab's ImageNav task reads). vln episodes go to export-vlnce; nogoal ones have no habitat format.

    Reads RUN_DIR/episodes/<id>/part-*.parquet and RUN_DIR/scenes/<id>/scene.json + meshes/, topdown.npz and
    semantic_map.json (what ObjectNav's view points see).

    Writes OUT/<task>/<split>/<split>.json.gz per task and split, OUT/scenes/<id>/<id>.glb and
    OUT/habitat_export.json (each task's habitat dataset type, data_path and scenes_dir; also printed). OUT
    must be new, empty or an earlier export-habitat output, outside RUN_DIR.
    """
    from sagebench.run_folder import claim_export_dir
    from sagebench.stages.export_habitat import MARKER, export_habitat

    with claim_export_dir(out, run_dir, "export-habitat", MARKER):
        for line in export_habitat(run_dir, out, split=split).lines():
            typer.echo(line)


@app.command("export-training", cls=settings_command("sagebench.settings.export_training:TrainingExportConfig"))
def export_training_cmd(
    ctx: typer.Context,
    run_dir: Annotated[Path, typer.Argument(metavar="RUN_DIR", callback=existing,
                                            help="Run directory (build-scene, gen-trajectories, export-usd).")],
    out: Annotated[Path, typer.Option("--out", help="Directory to write: new, or an interrupted export to resume.")],
) -> None:
    """Export imitation-learning data: each episode's reference path as discrete actions (SAGE-3D's derivation:
    turn towards each segment, then MOVE_FORWARD 0.25 m steps; TURN 15 degrees; STOP), executed in the
    simulator, with the view before every action (what the agent sees after the previous one, collisions
    included), the instruction and the action label.

    Reads RUN_DIR/episodes/<id>/part-*.parquet and RUN_DIR/scenes/<id>/ (scene.json, topdown.npz,
    gaussians.ply, scene.xml, colliders/); never writes into RUN_DIR.

    Writes OUT/export.json (settings, input hashes), OUT/shards/<split>-NNNNNN.tar (WebDataset: per step
    <key>.rgb.png, <key>.json and with --depth <key>.depth.png) and OUT/index.json; with --navila also
    OUT/navila/ (frames as PNG files and one annotations_<split>.json per split, as NaVILA's trainer reads
    them: answers "The next action is move forward 25 cm.").
    Deterministic; rerun the same command after an interruption to resume at the first unfinished shard.
    """
    from sagebench.stages.export_training import run_export_training

    config = settings(ctx)
    typer.echo(run_export_training(run_dir, out, config).summary())


@app.command("export-sage")
def export_sage_cmd(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN_DIR", callback=existing,
                                            help="Run directory with episodes/<id>/ and scenes/<id>/.")],
    out: Annotated[Path, typer.Option("--out", help="Directory for the GVLN files.")],
    scene: Annotated[str | None, typer.Option("--scene", help="Only this scene id (default: every scene).")] = None,
) -> None:
    """Export the episodes as SAGE-3D's GVLN trajectory files (SAGE-Bench's episode format).

    Positions and headings in SAGE-3D's 3D frame (the world turned by 180 degrees about Z, moved by an InteriorGS
    scene's sage_offset), one sample per trajectory, one instruction per episode row; SAGE-3D's episodes_adapter.py
    reads them. A goal in a room is named by the object nearest it (SAGE-Bench scores a goal by an object's box
    grown by 1 m); a trajectory whose goal has no object within 0.9 m is left out, and counted.

    Reads RUN_DIR/episodes/<id>/part-*.parquet and RUN_DIR/scenes/<id>/scene.json and semantic_map.json.

    Writes OUT/<id>/trajectories_<id>.json per scene (its vln episodes), OUT/<task-type>/<id>/trajectories_<id>.json
    for each other task (nogoalnav, objectnav, pointnav, imgnav: the run_benchmark.py --task-type that reads
    them) and OUT/sage_export.json (what was exported). OUT must be new, empty or an earlier export-sage
    output, outside RUN_DIR.
    """
    from sagebench.run_folder import claim_export_dir
    from sagebench.stages.export_sage import MARKER, export_sage

    with claim_export_dir(out, run_dir, "export-sage", MARKER):
        for line in export_sage(run_dir, out, scene_id=scene).lines():
            typer.echo(line)


@app.command("import-sage-episodes", cls=settings_command("sagebench.settings.import_sage_episodes:SageImportConfig"))
def import_sage_episodes_cmd(
    ctx: typer.Context,
    file: Annotated[Path, typer.Argument(metavar="FILE", callback=existing, help="GVLN trajectory file (SAGE-Bench's episodes for one scene).")],
    run: Annotated[Path, typer.Option("--run", callback=existing,
                                      help="Run directory holding the scene (scenes/<id>/ from build-scene).")],
    scene: Annotated[str | None, typer.Option(
        "--scene", help="Scene id in the run (default: the one named by the file's scene_name).")] = None,
    force: Force = False,
) -> None:
    """Turn SAGE-Bench's GVLN episodes for a scene into sagebench episodes, to roll out and evaluate them.

    Instruction types map to sagebench's (Attribute-based -> Attribute_Based, Area-based -> Area_Based, Default
    -> Single_Goal); Goal-less instructions become nogoal episodes from their sample's start (80 s, SAGE's
    budget), and a sample with SAGE-Bench's target_object, goal_position or target_image(_position) fields an
    objectnav, pointnav or imagenav episode (docs/tasks.md; an objectnav sample's goal viewpoints, which SAGE's
    files lack, are the navigable cells within its success radius of any instance of its category, as
    gen-trajectories finds them); instructions of an unknown type are left out and counted.

    Reads FILE and RUN/scenes/<id>/scene.json, topdown.npz and semantic_map.json. Values are checked as generated
    episodes are (radii > 0, the scene's instances and rooms, unique ids, paths of 2 or more points on the
    navigable map (a no-goal sample: its start), non-empty instructions); a path point at most 0.5 m off the
    navigable map is moved onto it and counted.

    Writes RUN/episodes/<id>/part-<split>-NNNNN.parquet, replacing that scene's episodes, and the stamp
    RUN/.stamps/<id>/import_sage.json in place of gen-trajectories'. Refuses (exit 2) a scene.json that
    differs from what build-scene's stamp records. RUN must be a sagebench run (unless --force), and is locked
    while it is written.
    """
    from sagebench.pipeline.stage_commands import import_sage_episodes
    from sagebench.run_folder import claim_run_dir

    config = settings(ctx)
    with claim_run_dir(run, "import-sage-episodes", force=force):
        for line in import_sage_episodes(file, run, config, scene_id=scene).lines():
            typer.echo(line)


@app.command("run", cls=settings_command("sagebench.settings.run:RunConfig", overrides=True))
def run_cmd(
    ctx: typer.Context,
    config: Annotated[Path, typer.Argument(metavar="CONFIG", callback=existing, help="TOML run config (scenes, out, per-stage settings).")],
    force: Force = False,
) -> None:
    """Run build-scene, gen-trajectories, export-usd and validate over many scenes.

    Reads CONFIG and every scene directory it names. Writes the run directory `out`: scenes/, episodes/,
    validation/, manifest.json, and hidden .stamps/ that let a re-run skip every stage whose inputs and
    settings are unchanged. Exit status 1 when some scene failed (the others still complete). `out` must be new,
    empty or a sagebench run (unless --force), and is locked while it is written.
    """
    from sagebench.pipeline.config import load_run_config
    from sagebench.pipeline.run import run_pipeline
    from sagebench.settings.option import fields_given
    from sagebench.settings.run import RunConfig

    from sagebench.errors import Interrupted

    cfg = load_run_config(config, **fields_given(RunConfig, given(ctx)))
    try:
        summary = run_pipeline(cfg, config, force=force)
    except KeyboardInterrupt:  # click would print "Aborted!"; the workers end quietly (pipeline/executors.py)
        raise Interrupted("interrupted: finished stages are kept; run again to go on from them") from None
    for line in summary.lines():
        typer.echo(line)
    if not summary.ok:
        raise typer.Exit(1)


@app.command("verify")
def verify_cmd(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN_DIR", callback=existing,
                                            help="Run directory with a manifest.json, or the stamps of a run made stage by stage.")],
    regenerate: Annotated[bool, typer.Option("--regenerate", help="Re-run CONFIG into a temporary directory and compare.")] = False,
    config: Annotated[Path | None, typer.Option("--config", callback=existing,
                                                help="The run's TOML config (needed with --regenerate).")] = None,
    workers: Annotated[int, typer.Option(help="Workers for --regenerate.")] = 1,
) -> None:
    """Check a run byte for byte against its manifest and the stamps of the stages that wrote it.

    Reads RUN_DIR/manifest.json, RUN_DIR/.stamps/ and every file of the run (with --regenerate also CONFIG
    and its scenes); a run made stage by stage (no manifest) is checked against its stamps alone. Writes
    nothing (--regenerate works in a temporary directory it removes). Exit status 1 names every file that
    differs and every scene whose stage failed in the run (the manifest records them).
    """
    from sagebench.errors import ConfigError
    from sagebench.pipeline.verify import regenerate_and_compare, verify_run

    if regenerate and config is None:
        raise ConfigError("--regenerate needs --config, the TOML the run was made with", field="--config")
    diff = regenerate_and_compare(run_dir, config, workers=workers) if regenerate else verify_run(run_dir)
    for line in diff.lines():
        typer.echo(line)
    if not diff.ok:
        raise typer.Exit(1)
    typer.echo(f"ok: every file of {run_dir} matches {diff.against}" + (" and a regeneration" if regenerate else ""))


@app.command("evaluate", cls=settings_command("sagebench.settings.evaluate:EvaluateConfig", before="--visualize"))
def evaluate_cmd(
    ctx: typer.Context,
    run_dir: Annotated[Path, typer.Option("--run", callback=existing, help="Run directory with episodes/<id>/ (and scenes/<id>/scene.xml).")],
    predictions: Annotated[Path, typer.Option("--predictions", callback=existing, help="Agent predictions, JSON Lines (one object per episode).")],
    out: Annotated[Path | None, typer.Option("--out", help="Write the results here as JSON (default: print only).")] = None,
    scene: Annotated[str | None, typer.Option("--scene", help="Score only this scene's episodes (default: every scene).")] = None,
    split: Annotated[str | None, typer.Option(
        "--split", autocompletion=splits,
        help="Score only this split's episodes: train, val_seen, val_unseen, test, trajectory_unseen or instruction_unseen (default: all).")] = None,
    visualize: Annotated[Path | None, typer.Option(
        "--visualize", help="Also draw one picture per scored episode into this folder: new, empty or an earlier "
                            "--visualize output, outside RUN.")] = None,
    force: ForceFile = False,
) -> None:
    """Score agent predictions: SR, OSR, SPL, NE, nDTW, SDTW, CSR, ICP, PS.

    Reads RUN/episodes/<id>/part-*.parquet and PREDICTIONS (JSON Lines: episode_id, poses
    [[x, y, z, yaw], ...], stopped, optional collision_intensity); for predictions without
    collision_intensity also RUN/scenes/<id>/scene.json and scene.xml, replaying each step against
    the colliders.

    Prints the means overall, per instruction level, per instruction type and per split, and which
    distance to the goal each metric used (on foot over the navigable map, or straight). Writes OUT
    (JSON: those means, every episode's metrics, missing episode ids, the settings) when given: never inside a
    sagebench run but in its baselines/, never over PREDICTIONS or a file sagebench did not write (unless
    --force).

    For the predictions of `sagebench rollout` it also reads PREDICTIONS' stem + _rollout.json and scores
    exactly the episodes the rollout was asked to run (one without a prediction, such as one the policy
    failed, scores the worst value of every metric), and prints the observations the agent had.

    With --visualize it writes VISUALIZE/trajectory_visualization_<scene>_<episode>.png per scored episode (the
    map, the reference path, the agent's path with the steps that touched something, start, goal and goal
    radius, the instruction and the metrics) and VISUALIZE/pictures.json (the predictions drawn, each
    episode's file).

    Unknown or duplicate episode ids, and episodes without a prediction (unless --allow-missing), are
    errors (exit status 2, nothing written).
    """
    from sagebench.evaluation.pictures import PICTURES_INDEX
    from sagebench.stages.evaluate import draw_pictures, evaluate

    config = settings(ctx)
    with (_claimed_folder(visualize, run_dir, "evaluate --visualize", PICTURES_INDEX, "--visualize")
          if visualize is not None else contextlib.nullcontext()):
        result = evaluate(run_dir, predictions, config, scene_id=scene, split=split, out=out, force=force)
        pictures = draw_pictures(run_dir, result, visualize) if visualize is not None else []
    typer.echo(result.table())
    if result.missing:
        typer.echo(f"{len(result.missing)} episodes had no prediction and were scored as failures")
    if out is not None:
        typer.echo(f"wrote {out}")
    if visualize is not None:
        typer.echo(f"wrote {len(pictures)} pictures into {visualize}")


@contextlib.contextmanager
def _claimed_folder(out: Path, run_dir: Path, command: str, marker: str, option: str) -> Iterator[Path]:
    """run_folder.claim_export_dir for a folder that `option` names: its refusals name that option, not --out."""
    from sagebench.run_folder import claim_export_dir

    with contextlib.ExitStack() as stack:
        try:
            stack.enter_context(claim_export_dir(out, run_dir, command, marker))
        except ConfigError as err:
            raise ConfigError(err.detail.replace("--out", option), path=err.path, field=option) from None
        yield out


@app.command("report", cls=settings_command("sagebench.settings.report:ReportConfig"))
def report_cmd(
    ctx: typer.Context,
    run_dir: Annotated[Path, typer.Argument(metavar="RUN", callback=existing,
                                            help="Run directory with episodes/<id>/ and scenes/<id>/ (build-scene, "
                                                 "gen-trajectories).")],
    out: Annotated[Path, typer.Option("--out", help="Folder of the report: new, empty or an earlier report, outside "
                                                     "RUN.")],
    predictions: Annotated[list[Path] | None, typer.Option(
        "--predictions", callback=existing,
        help="Agent predictions (JSON Lines) to show and compare; repeat for more agents.")] = None,
    scene: Annotated[str | None, typer.Option("--scene", help="Only this scene (default: every scene).")] = None,
) -> None:
    """Write a static HTML report of a run and of agents' predictions: open OUT/index.html in a browser (no server,
    no network).

    Pages: the overview (scenes, episodes by split and instruction type, validation pass rates and failures by
    reason, the dataset card's facts, the agents' means), a page per scene (its map with every trajectory,
    filtered by split and type, and its episodes) and a page per episode (the instruction, the path on the map,
    the start and goal views, validate's result and, with predictions, each agent's path, contact per step and
    metrics); with predictions also OUT/agents.html, every episode's metrics side by side, sortable.

    Reads RUN/episodes/<id>/, RUN/scenes/<id>/ (topdown.npz, topdown.png, and scene.json and gaussians.ply for
    the views), RUN/validation/<id>/ and RUN/reports/<id>/ where validate wrote them, RUN/manifest.json, and each
    PREDICTIONS as evaluate reads it (episodes without a prediction are shown as such).

    Writes OUT/index.html, agents.html, scenes/, episodes/, img/ (the maps and the views), report.css, report.js
    and report.json (what the report shows, its files). OUT must be new, empty or an earlier report, outside RUN.
    """
    from sagebench.report.write import REPORT_INDEX, write_report

    config = settings(ctx)
    with _claimed_folder(out, run_dir, "report", REPORT_INDEX, "--out"):
        for line in write_report(run_dir, predictions or [], out, config, scene_id=scene).lines():
            typer.echo(line)


@app.command("baseline", cls=settings_command("sagebench.settings.baseline:BaselineConfig"))
def baseline_cmd(
    ctx: typer.Context,
    run_dir: Annotated[Path, typer.Option("--run", callback=existing, help="Run directory with episodes/<id>/ and scenes/<id>/scene.xml.")],
    out: Annotated[Path, typer.Option("--out", help="Predictions file to write (JSON Lines).")],
    scene: Annotated[str | None, typer.Option("--scene", help="Only this scene's episodes (default: every scene).")] = None,
    force: ForceFile = False,
) -> None:
    """Run a built-in policy closed-loop over every episode: `rollout --policy AGENT --obs none`.

    The same loop, policies and simulator as `sagebench rollout` (VLN-CE's discrete actions, MuJoCo, c(t)
    measured by the simulator), without rendering: oracle follows the reference path; straight turns
    towards the goal and moves at it, stopping within the goal radius or after 4 forward moves without
    progress; random wanders (seeded per episode).

    Reads RUN/episodes/<id>/part-*.parquet and RUN/scenes/<id>/scene.json, topdown.npz and scene.xml
    (export-usd). Writes OUT: one JSON line per episode with poses, stopped and the simulator's
    collision_intensity, ready for `sagebench evaluate`, and OUT's stem + _rollout.json (the rollout's record:
    its episodes, and that the baseline reads the pose and the episode). OUT is claimed as rollout claims it.
    """
    from sagebench.stages.rollout import run_baseline

    config = settings(ctx)
    typer.echo(run_baseline(run_dir, out, config, scene_id=scene, force=force).summary())


@app.command("rollout", cls=settings_command("sagebench.settings.rollout:RolloutConfig"))
def rollout_cmd(
    ctx: typer.Context,
    run_dir: Annotated[Path, typer.Option("--run", callback=existing, help="Run directory (build-scene, gen-trajectories, export-usd).")],
    out: Annotated[Path, typer.Option("--out", help="Predictions file to write (JSON Lines).")],
    scene: Annotated[str | None, typer.Option("--scene", help="Only this scene's episodes (default: every scene).")] = None,
    resume: Annotated[bool, typer.Option("--resume", help="Run the episodes a killed or stopped rollout into OUT "
                                                          "did not finish, with its settings.")] = False,
    force: ForceFile = False,
) -> None:
    """Run a policy closed-loop in the simulator: it sees rendered views, acts (STOP, MOVE_FORWARD 0.25 m,
    TURN_LEFT / TURN_RIGHT 15 degrees, or continuous v, omega, stop), MuJoCo moves the agent and measures each
    step's collision intensity.

    A URL policy gets one HTTP POST per step and episode (docs: the policy protocol); oracle, straight and random
    are the built-in baselines; vlnce:MODULE:NAME imports an agent with habitat's Agent interface and runs it
    in-process with VLN-CE's observations and actions. Reads RUN/episodes/<id>/, RUN/scenes/<id>/ (scene.json, topdown.npz,
    gaussians.ply, scene.xml, colliders/). Writes OUT (one JSON line per episode, appended as each ends, in run
    order once all have: poses, stopped, the simulator's collision_intensity marked intensity_source
    "simulator"), OUT's stem + _rollout.json (the episodes asked for, the observations the policy had, the
    episodes the policy failed) and, when rgb is rendered, OUT's stem + _contact_sheet.png (start, middle and
    end views of the first 4 episodes). Exit status 1 when episodes are left to run (--resume runs them).

    OUT is held by this rollout alone (a second rollout into it is refused, naming its pid), lies outside every
    sagebench run but in its baselines/, and an existing OUT, record or sheet that sagebench did not write is
    never replaced (unless --force).
    """
    from sagebench.stages.rollout import make_config, run_rollout

    config = make_config(given(ctx), resume=resume)
    result = run_rollout(run_dir, out, config, scene_id=scene, resume=resume, force=force)
    typer.echo(result.summary())
    if not result.complete:
        raise typer.Exit(1)


def _add_examples() -> None:
    """End each command's --help with its worked example (sagebench/cli_examples.py; docs/cli.md shows them)."""
    from sagebench.cli_examples import epilog

    for info in app.registered_commands:
        info.epilog = epilog(info.name)


_add_examples()


def main(argv: list[str] | None = None) -> None:
    """The CLI: the one place where errors become one line and exit status 2 (130 for Ctrl-C).

    Besides SagebenchError, an OSError no stage turned into one (a permission, a full disk) and Ctrl-C at any
    moment end in one line too; every write is atomic, so neither leaves a partial output."""
    try:
        with interrupts_noted():
            app(args=hoist_global_flags(sys.argv[1:] if argv is None else list(argv)), prog_name="sagebench")
    except SystemExit as done:  # typer turns Ctrl-C in a command into a silent exit 130
        silent = done.code == 130 and isinstance(getattr(done.__context__, "__cause__", None), KeyboardInterrupt)
        swallowed = done.code in (0, None) and interrupted()  # a library caught the Ctrl-C and the command went on
        if (silent or swallowed) and not SETTINGS.debug:
            _fail(Interrupted(INTERRUPTED))
        raise
    except (SagebenchError, OSError, KeyboardInterrupt) as err:
        if SETTINGS.debug:
            raise
        _fail(err if isinstance(err, SagebenchError) else Interrupted(INTERRUPTED) if isinstance(err, KeyboardInterrupt)
              else OutputError(err.strerror or str(err), path=err.filename))
    except Exception:
        # a library swallowed the Ctrl-C and failed on what it left (trimesh keeps an ExceptionWrapper in place of
        # a module whose import was interrupted; its next annotation `ExceptionWrapper | None` is a TypeError)
        if interrupted() and not SETTINGS.debug:
            _fail(Interrupted(INTERRUPTED))
        raise


INTERRUPTED = "interrupted: the work in progress was not written"


def _fail(err: SagebenchError) -> None:
    print(f"error: {err}", file=sys.stderr)
    sys.exit(err.exit_code)
