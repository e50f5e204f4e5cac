"""The `sagebench` command: parses options, calls one library function per command, prints.

Every SagebenchError becomes one line on stderr and exit status 2, here and nowhere else.
"""

from __future__ import annotations

import contextlib
import importlib
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated

import typer
import typer.core

from sagebench.errors import ConfigError, Interrupted, OutputError, SagebenchError
from sagebench.ui import SETTINGS, interrupted, interrupts_noted

app = typer.Typer(
    add_completion=True,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,  # click's plain help: rewrapped to the terminal (80 columns at most), flags without a value
    help="Turn artist-made indoor scenes into a physically executable VLN benchmark.",
)


def _defaults_from(settings: str, options: str = "OPTIONS") -> type[typer.core.TyperCommand]:
    """A command class whose --help adds "(default X)" to each option, X read from the settings model
    "module:Model" through the module's OPTIONS (or `options`: option -> field path) when help is shown: the defaults have
    one source, and a command that is run rather than asked for help imports nothing more."""

    class Command(typer.core.TyperCommand):
        def format_help(self, ctx, formatter) -> None:  # noqa: ANN001 - click's signature
            if not getattr(self, "_defaults_shown", False):
                from sagebench.config import option_defaults

                module_name, model = settings.split(":")
                module = importlib.import_module(module_name)
                defaults = option_defaults(getattr(module, model), getattr(module, options))
                for param in self.params:
                    value = next((defaults[o] for o in param.opts if o in defaults), None)
                    if value not in (None, ()) and not isinstance(value, bool) and not param.required:
                        shown = f"{value:g}" if isinstance(value, float) else str(value)
                        param.help = f"{param.help.removesuffix('.')} (default {shown})."
                self._defaults_shown = True
            super().format_help(ctx, formatter)

    return Command


RENDERER_HELP = "Renderer: cpu (the reference), gsplat (CUDA GPU, pip install 'sagebench[gpu]') or auto (gsplat when it can run here)."


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


def values_of(settings: str, option: str, options: str = "OPTIONS"):
    """Shell completion of an option's values: the Literal values of the settings field it sets ("module:Model",
    through the module's OPTIONS or `options`), read only when a shell asks."""

    def complete(incomplete: str) -> list[str]:
        from sagebench.config import option_choices

        module_name, model = settings.split(":")
        module = importlib.import_module(module_name)
        return [v for v in option_choices(getattr(module, model), getattr(module, options), option)
                if v.startswith(incomplete)]

    return complete


def splits(incomplete: str) -> list[str]:
    """Shell completion of --split: the benchmark's splits."""
    from sagebench.episodes.splits import SPLITS

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


@app.command("import-interiorgs", cls=_defaults_from("sagebench.stages.import_interiorgs:InteriorGSConfig"))
def import_interiorgs_cmd(
    src: Annotated[Path, typer.Argument(
        metavar="SRC", callback=existing, help="InteriorGS scene folder (3dgs_compressed.ply, labels.json, structure.json, "
                                "occupancy.png, occupancy.json).")],
    out: Annotated[Path, typer.Option("--out", help="Scene directory to create: absent, empty or an earlier import "
                                                     "(replaced whole).")],
    collision_usd: Annotated[Path | None, typer.Option(
        "--collision-usd", callback=existing,
        help="SAGE-3D's collision USD for this scene: its meshes replace the surfaces made from Gaussians for the "
             "objects they match.")] = None,
    voxel: Annotated[float | None, typer.Option(help="Voxel side of the object surfaces, m.")] = None,
    min_opacity: Annotated[float | None, typer.Option(help="Summed opacity a voxel needs to be solid.")] = None,
    max_parts: Annotated[int | None, typer.Option(help="Convex parts per object surface at most.")] = None,
    force: Annotated[bool, typer.Option("--force", help="Replace OUT whatever it holds, unless it is SRC or "
                                                        "COLLISION_USD, lies inside one or holds one.")] = False,
) -> None:
    """Turn an InteriorGS scene folder (3D Gaussians and labels, no meshes) into a sagebench scene.

    Reads SRC/3dgs_compressed.ply (SuperSplat's compressed layout; or 3dgs.ply in the INRIA layout),
    labels.json, structure.json, occupancy.png and occupancy.json, and COLLISION_USD when given.

    Writes OUT/scene.json, OUT/meshes/*.ply (walls with their openings, floor and ceiling slabs, and each
    object's surface made from its own Gaussians), OUT/gaussians.ply (the Gaussians with instance ids),
    OUT/interiorgs_import.json (shares of Gaussians per outcome, doors, the occupancy agreement) and
    OUT/occupancy_check.png (occupancy.png against the imported geometry). OUT must be new, empty or an
    earlier import (unless --force), and never SRC or COLLISION_USD, inside one, a folder holding one, or
    inside a sagebench run. build-scene and run also take SRC directly.
    """
    from sagebench.stages.import_interiorgs import import_interiorgs_scene, make_config

    config = make_config(voxel=voxel, min_opacity=min_opacity, max_parts=max_parts)
    typer.echo(import_interiorgs_scene(src, out, config, collision_usd=collision_usd, force=force).summary())


@app.command("build-scene", cls=_defaults_from("sagebench.stages.build_scene:BuildSceneConfig"))
def build_scene_cmd(
    scene_dir: Annotated[Path, typer.Argument(
        metavar="SCENE_DIR", callback=existing, help="Artist scene directory (scene.json + meshes) or InteriorGS scene folder.")],
    out: Annotated[Path, typer.Option("--out", help="Run directory; writes OUT/scenes/<scene_id>/.")],
    resolution: Annotated[float | None, typer.Option(help="Grid cell side, m.")] = None,
    band_min: Annotated[float | None, typer.Option(
        help="Lowest blocking height above the floor, m: the agent body's bottom (its clearance).")] = None,
    band_max: Annotated[float | None, typer.Option(
        help="Highest blocking height above the floor, m: the agent body's top (its height).")] = None,
    sample_density: Annotated[float | None, typer.Option(help="Footprint surface samples per m^2.")] = None,
    wall_gap: Annotated[float | None, typer.Option(help="Join room floors across walls up to this thick, m.")] = None,
    agent_radius: Annotated[float | None, typer.Option(help="Agent radius for the navigable map, m.")] = None,
    seed: Annotated[int | None, typer.Option(help="Seed of the footprint and Gaussian sampling.")] = None,
    object_density: Annotated[float | None, typer.Option(help="Sampled Gaussians per m^2 on objects.")] = None,
    structure_density: Annotated[float | None, typer.Option(help="Sampled Gaussians per m^2 on walls, floors, ceilings.")] = None,
    prune: Annotated[float | None, typer.Option(help="Drop this fraction of Gaussians by blending contribution.")] = None,
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
    from sagebench.stages.build_scene import make_config

    config = make_config(resolution=resolution, band_min=band_min, band_max=band_max, sample_density=sample_density,
                         wall_gap=wall_gap, agent_radius=agent_radius, seed=seed, prune=prune,
                         object_density=object_density, structure_density=structure_density)
    check_scenes_apart(out, [scene_dir])
    with claim_run_dir(out, "build-scene", force=force):
        typer.echo(build_scene(scene_dir, out, config).summary())


@app.command("gen-trajectories", cls=_defaults_from("sagebench.stages.gen_trajectories:GenTrajectoriesConfig"))
def gen_trajectories_cmd(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN_DIR", callback=existing, help="Run directory that build-scene wrote (RUN/scenes/<id>/).")],
    scene: Annotated[str | None, typer.Option("--scene", help="Only this scene id (default: every scene).")] = None,
    per_scene: Annotated[int | None, typer.Option(help="Distinct trajectories per scene.")] = None,
    seed: Annotated[int | None, typer.Option(help="Seed of sampling and wording.")] = None,
    shard_mb: Annotated[float | None, typer.Option(help="Largest Parquet shard, MB (one split per shard).")] = None,
    instructions: Annotated[
        str | None, typer.Option(autocompletion=values_of("sagebench.stages.gen_trajectories:GenTrajectoriesConfig",
                                                          "--instructions"),
                                 help="template: two low-level rows and one high-level row per trajectory; llm: the "
                                      "high-level row from a chat model; none: bare trajectories.")
    ] = None,
    min_geodesic: Annotated[float | None, typer.Option(help="Shortest accepted path, m.")] = None,
    max_geodesic: Annotated[float | None, typer.Option(help="Longest accepted path, m.")] = None,
    goal_radius: Annotated[float | None, typer.Option(help="Success radius written with each episode, m.")] = None,
    llm_base_url: Annotated[str | None, typer.Option(
        help="OpenAI-compatible API root for --instructions llm, e.g. http://localhost:8000/v1.")] = None,
    llm_model: Annotated[str | None, typer.Option(help="Chat model name for --instructions llm.")] = None,
    llm_cache_dir: Annotated[Path | None, typer.Option(
        help="Answer cache, keyed by sha256 of (model, prompt) (default: the user cache directory).")] = None,
    llm_concurrency: Annotated[int | None, typer.Option(
        help="LLM requests in flight at once (default: the slots the server reports, else 1 for a server on this "
             "machine or network, else 4).")] = None,
    llm_timeout: Annotated[float | None, typer.Option(
        help="Deadline of one whole LLM request (connect to last byte), s.")] = None,
    llm_attempts: Annotated[int | None, typer.Option(help="HTTP attempts per LLM request (429, 5xx, timeouts).")] = None,
    llm_temperature: Annotated[float | None, typer.Option(help="Sampling temperature of the LLM.")] = None,
    llm_max_tokens: Annotated[int | None, typer.Option(help="Longest LLM answer, tokens.")] = None,
    llm_min_share: Annotated[float | None, typer.Option(
        help="Exit 1 (writing nothing) when a scene gets a smaller share of high-level rows from the LLM; with no "
             "LLM row it always does.")] = None,
    llm_response_format: Annotated[str | None, typer.Option(
        help="How to ask the LLM for JSON: auto (json_schema, else json_object, else none, decided by the first "
             "request), json_schema, json_object or none.")] = None,
    llm_refresh: Annotated[bool | None, typer.Option(
        "--llm-refresh", help="Ask the LLM again even for prompts the answer cache holds.")] = None,
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

    llm = {k: v for k, v in {"base_url": llm_base_url, "model": llm_model, "cache_dir": llm_cache_dir,
                             "concurrency": llm_concurrency, "timeout_s": llm_timeout, "max_attempts": llm_attempts,
                             "temperature": llm_temperature, "max_tokens": llm_max_tokens,
                             "min_share": llm_min_share, "response_format": llm_response_format,
                             "refresh": llm_refresh}.items() if v is not None}
    config = make_config(per_scene=per_scene, seed=seed, shard_mb=shard_mb, instructions=instructions,
                         min_geodesic_m=min_geodesic, max_geodesic_m=max_geodesic, goal_radius_m=goal_radius,
                         llm=llm or None)
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


@app.command("render", cls=_defaults_from("sagebench.stages.render:RenderConfig"))
def render_cmd(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN_DIR", callback=existing, help="Run directory with scenes/<scene_id>/ from build-scene.")],
    scene: Annotated[str, typer.Option("--scene", help="Scene id (a directory under RUN_DIR/scenes).")],
    pose: Annotated[str, typer.Option("--pose", help="X,Y,YAW: camera position on the floor, m, and heading, rad.")],
    out: Annotated[Path, typer.Option("--out", help="PNG file to write.")],
    camera_height: Annotated[float | None, typer.Option(help="Camera above the floor, m.")] = None,
    pitch: Annotated[float | None, typer.Option(help="Camera tilt up, degrees (negative looks down).")] = None,
    hfov: Annotated[float | None, typer.Option(help="Horizontal field of view, degrees.")] = None,
    width: Annotated[int | None, typer.Option(help="Image width, px.")] = None,
    height: Annotated[int | None, typer.Option(help="Image height, px.")] = None,
    depth_out: Annotated[Path | None, typer.Option("--depth-out", help="Also write depth, float32 .npy, m.")] = None,
    instance_out: Annotated[Path | None, typer.Option("--instance-out", help="Also write instance ids, int32 .npy.")] = None,
    renderer: Annotated[str | None, typer.Option(help=RENDERER_HELP)] = None,
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
    from sagebench.stages.render import make_render_config, parse_pose, render_files

    config = make_render_config(camera_height=camera_height, hfov=hfov, pitch_deg=pitch, width=width, height=height,
                                renderer=renderer)
    for path in render_files(run_dir, scene, parse_pose(pose), config, out, depth_out=depth_out,
                             instance_out=instance_out, force=force):
        typer.echo(f"wrote {path}")


@app.command("export-usd", cls=_defaults_from("sagebench.stages.export_usd:ExportConfig"))
def export_usd_cmd(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN_DIR", callback=existing, help="Run directory that build-scene wrote (RUN/scenes/<id>/).")],
    scene: Annotated[str | None, typer.Option("--scene", help="Export only this scene id (default: every scene).")] = None,
    cache_dir: Annotated[
        Path | None, typer.Option("--cache-dir", help="Collider piece cache (default: the user cache directory).")
    ] = None,
    workers: Annotated[int | None, typer.Option(help="Processes splitting meshes, decomposing pieces and measuring colliders.")] = None,
    colliders: Annotated[
        str | None, typer.Option(autocompletion=values_of("sagebench.stages.export_usd:ExportConfig", "--colliders"), help="quality (CoACD), balanced (hull, voxel or CoACD, whichever first fits the "
                                      "agent band) or fast (hull or voxel).")
    ] = None,
    max_parts: Annotated[int | None, typer.Option(help="Part budget per object; parts are merged to stay within it.")] = None,
    piece_limit: Annotated[
        float | None, typer.Option(help="Safety stop, s: the export fails, naming the piece, when one method runs "
                                        "longer on it (it never picks a method).")
    ] = None,
    band_tolerance: Annotated[
        float | None, typer.Option(help="A method is good enough within this many cm of the piece's band footprint.")
    ] = None,
    coacd_threshold: Annotated[
        float | None, typer.Option(help="CoACD concavity threshold; smaller gives more parts.")
    ] = None,
    coacd_max_hulls: Annotated[
        int | None, typer.Option(help="Most CoACD parts per concave piece, -1 for the part budget.")
    ] = None,
    coacd_max_faces: Annotated[
        int | None, typer.Option(help="CoACD is tried only on pieces of at most this many faces.")
    ] = None,
    coacd_preprocess: Annotated[
        str | None, typer.Option(autocompletion=values_of("sagebench.stages.export_usd:ExportConfig", "--coacd-preprocess"),
                                 help="CoACD manifold preprocessing: auto, on or off.")
    ] = None,
    usdz: Annotated[
        bool | None, typer.Option("--usdz", help="Also write scene.usdz (the stage and its layers in one package).")
    ] = None,
    gaussians: Annotated[str | None, typer.Option(
        autocompletion=values_of("sagebench.stages.export_usd:ExportConfig", "--gaussians"), help="particlefield: ParticleField3DGaussianSplat prims per object (Isaac Sim 6); nurec: "
             "gaussians.usdz, NuRec as NVIDIA 3DGRUT's ply_to_usd writes it (Isaac Sim 5).")] = None,
    layout: Annotated[str | None, typer.Option(
        autocompletion=values_of("sagebench.stages.export_usd:ExportConfig", "--layout"), help="sagebench, or sage: also sage/<id>.usda in SAGE-3D's template form with its collision payload "
             "sage/<id>_collision.usd (needs --gaussians nurec).")] = None,
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
    from sagebench.stages.export_usd import make_config

    config = make_config(colliders=colliders, max_parts=max_parts, piece_limit=piece_limit,
                         band_tolerance=band_tolerance, coacd_threshold=coacd_threshold,
                         coacd_max_hulls=coacd_max_hulls, coacd_max_faces=coacd_max_faces,
                         coacd_preprocess=coacd_preprocess, workers=workers, usdz=usdz, gaussians=gaussians,
                         layout=layout)
    with claim_run_dir(run_dir, "export-usd", force=force):
        for result in export_usd(run_dir, config, scene_id=scene, cache_dir=cache_dir):
            typer.echo(result.line())


@app.command("validate", cls=_defaults_from("sagebench.stages.validate:ValidateConfig"))
def validate_cmd(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN_DIR", callback=existing, help="Run directory with scenes/<id>/ (build-scene, export-usd) and episodes/<id>/.")],
    scene: Annotated[str | None, typer.Option("--scene", help="Validate only this scene id (default: every scene).")] = None,
    frames_per_scene: Annotated[
        int | None, typer.Option(help="Trajectories per scene rendered at start, middle and goal.")
    ] = None,
    depth_tolerance: Annotated[
        float | None, typer.Option(help="Largest median |splat - collider depth| per frame, m.")
    ] = None,
    workers: Annotated[int | None, typer.Option(help="Threads stepping the MuJoCo replays.")] = None,
    renderer: Annotated[str | None, typer.Option(help=RENDERER_HELP + " Instance-id frames come from the CPU.")] = None,
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
    from sagebench.stages.validate import make_config

    config = make_config(frames_per_scene=frames_per_scene, depth_tolerance=depth_tolerance, workers=workers,
                         renderer=renderer)
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


@app.command("export-vlnce")
def export_vlnce_cmd(
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
    Y up) for habitat-sim. OUT must be new, empty or an earlier export-vlnce output, outside RUN_DIR.
    """
    from sagebench.run_folder import claim_export_dir
    from sagebench.stages.export_vlnce import OPTS_FILE, export_vlnce

    with claim_export_dir(out, run_dir, "export-vlnce", OPTS_FILE):
        for line in export_vlnce(run_dir, out, split=split).lines():
            typer.echo(line)


@app.command("export-training", cls=_defaults_from("sagebench.stages.export_training:TrainingExportConfig"))
def export_training_cmd(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN_DIR", callback=existing,
                                            help="Run directory (build-scene, gen-trajectories, export-usd).")],
    out: Annotated[Path, typer.Option("--out", help="Directory to write: new, or an interrupted export to resume.")],
    split: Annotated[str | None, typer.Option("--split", autocompletion=splits,
                                              help="Export only this split (default: every split).")] = None,
    depth: Annotated[bool | None, typer.Option("--depth", help="Also write each view's depth (16-bit PNG, mm).")] = None,
    width: Annotated[int | None, typer.Option(help="View width, px.")] = None,
    height: Annotated[int | None, typer.Option(help="View height, px.")] = None,
    renderer: Annotated[str | None, typer.Option(help=RENDERER_HELP)] = None,
    episodes_per_shard: Annotated[int | None, typer.Option(help="Episodes per tar shard.")] = None,
    batch: Annotated[int | None, typer.Option(help="Episodes stepped and rendered together.")] = None,
    workers: Annotated[int | None, typer.Option(help="Threads stepping MuJoCo.")] = None,
    navila: Annotated[bool | None, typer.Option("--navila", help="Also write NaVILA's layout (OUT/navila/).")] = None,
) -> None:
    """Export imitation-learning data: each episode's reference path as discrete actions (SAGE-3D's derivation:
    turn towards each segment, then MOVE_FORWARD 0.25 m steps; TURN 15 degrees; STOP), executed in the
    simulator, with the view before every action (what the agent sees after the previous one, collisions
    included), the instruction and the action label.

    Reads RUN_DIR/episodes/<id>/part-*.parquet and RUN_DIR/scenes/<id>/ (scene.json, topdown.npz,
    gaussians.ply, scene.xml, colliders/); never writes into RUN_DIR.

    Writes OUT/export.json (settings, input hashes), OUT/shards/<split>-NNNNNN.tar (WebDataset: per step
    <key>.rgb.png, <key>.json and with --depth <key>.depth.png) and OUT/index.json; with --navila also
    OUT/navila/ (frames as PNG files and annotations_part_NNN.json as SAGE-3D builds NaVILA's training set).
    Deterministic; rerun the same command after an interruption to resume at the first unfinished shard.
    """
    from sagebench.stages.export_training import make_config, run_export_training

    config = make_config(split=split, depth=depth, width=width, height=height, renderer=renderer,
                         episodes_per_shard=episodes_per_shard, batch=batch, workers=workers, navila=navila)
    typer.echo(run_export_training(run_dir, out, config).summary())



@app.command("export-sage")
def export_sage_cmd(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN_DIR", callback=existing,
                                            help="Run directory with episodes/<id>/ and scenes/<id>/.")],
    out: Annotated[Path, typer.Option("--out", help="Directory for the GVLN files.")],
    scene: Annotated[str | None, typer.Option("--scene", help="Only this scene id (default: every scene).")] = None,
) -> None:
    """Export the episodes as SAGE-3D's GVLN trajectory files (SAGE-Bench's episode format).

    Positions and headings in SAGE-3D's 3D frame (the world turned by 180 degrees about Z), one sample per
    trajectory, one instruction per episode row; SAGE-3D's episodes_adapter.py reads them.

    Reads RUN_DIR/episodes/<id>/part-*.parquet and RUN_DIR/scenes/<id>/scene.json.

    Writes OUT/<id>/trajectories_<id>.json per scene and OUT/sage_export.json (what was exported). OUT must
    be new, empty or an earlier export-sage output, outside RUN_DIR.
    """
    from sagebench.run_folder import claim_export_dir
    from sagebench.stages.export_sage import MARKER, export_sage

    with claim_export_dir(out, run_dir, "export-sage", MARKER):
        for line in export_sage(run_dir, out, scene_id=scene).lines():
            typer.echo(line)


@app.command("import-sage-episodes", cls=_defaults_from("sagebench.stages.import_sage:SageImportConfig"))
def import_sage_episodes_cmd(
    file: Annotated[Path, typer.Argument(metavar="FILE", callback=existing, help="GVLN trajectory file (SAGE-Bench's episodes for one scene).")],
    run: Annotated[Path, typer.Option("--run", callback=existing,
                                      help="Run directory holding the scene (scenes/<id>/ from build-scene).")],
    scene: Annotated[str | None, typer.Option(
        "--scene", help="Scene id in the run (default: the one named by the file's scene_name).")] = None,
    goal_radius: Annotated[float | None, typer.Option(help="Success radius, m, where the file has none (SAGE-3D's).")] = None,
    split: Annotated[str | None, typer.Option(help="Split of the rows where the file has none.")] = None,
    force: Force = False,
) -> None:
    """Turn SAGE-Bench's GVLN episodes for a scene into sagebench episodes, to roll out and evaluate them.

    Instruction types map to sagebench's (Attribute-based -> Attribute_Based, Area-based -> Area_Based, Default
    -> Single_Goal); instructions of a type with no goal (Goal-less) are left out and counted.

    Reads FILE and RUN/scenes/<id>/scene.json and topdown.npz. Values are checked as generated episodes are
    (radii > 0, the scene's instances and rooms, unique ids, paths of 2 or more points on the navigable map,
    non-empty instructions); a path point at most 0.5 m off the navigable map is moved onto it and counted.

    Writes RUN/episodes/<id>/part-<split>-NNNNN.parquet, replacing that scene's episodes, and the stamp
    RUN/.stamps/<id>/import_sage.json in place of gen-trajectories'. Refuses (exit 2) a scene.json that
    differs from what build-scene's stamp records. RUN must be a sagebench run (unless --force), and is locked
    while it is written.
    """
    from sagebench.pipeline.stage_commands import import_sage_episodes
    from sagebench.run_folder import claim_run_dir
    from sagebench.stages.import_sage import make_config

    config = make_config(goal_radius=goal_radius, split=split)
    with claim_run_dir(run, "import-sage-episodes", force=force):
        for line in import_sage_episodes(file, run, config, scene_id=scene).lines():
            typer.echo(line)


@app.command("run")
def run_cmd(
    config: Annotated[Path, typer.Argument(metavar="CONFIG", callback=existing, help="TOML run config (scenes, out, per-stage settings).")],
    workers: Annotated[int | None, typer.Option(help="Scene-stage tasks at once (default: the config's, else 1).")] = None,
    executor: Annotated[str | None, typer.Option(help="local or ray (default: the config's, else local).")] = None,
    ray_address: Annotated[str | None, typer.Option("--ray-address", help="Ray cluster; none starts a local Ray.")] = None,
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

    from sagebench.errors import Interrupted

    cfg = load_run_config(config, workers=workers, executor=executor, ray_address=ray_address)
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


@app.command("evaluate", cls=_defaults_from("sagebench.stages.evaluate:EvaluateConfig"))
def evaluate_cmd(
    run_dir: Annotated[Path, typer.Option("--run", callback=existing, help="Run directory with episodes/<id>/ (and scenes/<id>/scene.xml).")],
    predictions: Annotated[Path, typer.Option("--predictions", callback=existing, help="Agent predictions, JSON Lines (one object per episode).")],
    out: Annotated[Path | None, typer.Option("--out", help="Write the results here as JSON (default: print only).")] = None,
    scene: Annotated[str | None, typer.Option("--scene", help="Score only this scene's episodes (default: every scene).")] = None,
    split: Annotated[str | None, typer.Option(
        "--split", autocompletion=splits,
        help="Score only this split's episodes: train, val_seen, val_unseen or test (default: all).")] = None,
    allow_missing: Annotated[
        bool, typer.Option("--allow-missing", help="Score episodes without a prediction as failures instead of stopping.")
    ] = False,
    all_episodes: Annotated[
        bool, typer.Option("--all-episodes", help="With a rollout's predictions: score every episode of the run (or "
                                                  "--scene/--split), not only those the rollout was asked to run.")
    ] = False,
    start_tolerance: Annotated[
        float | None, typer.Option(help="Largest distance of the first pose from the episode's start, m.")
    ] = None,
    workers: Annotated[int | None, typer.Option(help="Threads replaying poses for collision intensity.")] = None,
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
    from sagebench.stages.evaluate import draw_pictures, evaluate, make_config

    config = make_config(allow_missing=allow_missing, all_episodes=all_episodes, start_tolerance=start_tolerance,
                         workers=workers)
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


@app.command("report", cls=_defaults_from("sagebench.report.write:ReportConfig"))
def report_cmd(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN", callback=existing,
                                            help="Run directory with episodes/<id>/ and scenes/<id>/ (build-scene, "
                                                 "gen-trajectories).")],
    out: Annotated[Path, typer.Option("--out", help="Folder of the report: new, empty or an earlier report, outside "
                                                     "RUN.")],
    predictions: Annotated[list[Path] | None, typer.Option(
        "--predictions", callback=existing,
        help="Agent predictions (JSON Lines) to show and compare; repeat for more agents.")] = None,
    scene: Annotated[str | None, typer.Option("--scene", help="Only this scene (default: every scene).")] = None,
    no_views: Annotated[bool, typer.Option("--no-views", help="Leave out the start and goal views (nothing is "
                                                               "rendered).")] = False,
    renderer: Annotated[str | None, typer.Option(help=RENDERER_HELP)] = None,
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
    from sagebench.report.write import REPORT_INDEX, make_config, write_report

    config = make_config(views=False if no_views else None, renderer=renderer)
    with _claimed_folder(out, run_dir, "report", REPORT_INDEX, "--out"):
        for line in write_report(run_dir, predictions or [], out, config, scene_id=scene).lines():
            typer.echo(line)


@app.command("baseline", cls=_defaults_from("sagebench.stages.rollout:BaselineConfig", "BASELINE_OPTIONS"))
def baseline_cmd(
    agent: Annotated[str, typer.Option("--agent", help="oracle, straight or random.", autocompletion=values_of(
        "sagebench.stages.rollout:BaselineConfig", "--agent", "BASELINE_OPTIONS"))],
    run_dir: Annotated[Path, typer.Option("--run", callback=existing, help="Run directory with episodes/<id>/ and scenes/<id>/scene.xml.")],
    out: Annotated[Path, typer.Option("--out", help="Predictions file to write (JSON Lines).")],
    seed: Annotated[int | None, typer.Option(help="Seed of the random agent.")] = None,
    scene: Annotated[str | None, typer.Option("--scene", help="Only this scene's episodes (default: every scene).")] = None,
    max_actions: Annotated[int | None, typer.Option(help="Actions per episode before it ends unstopped.")] = None,
    workers: Annotated[int | None, typer.Option(help="Threads stepping the MuJoCo agents.")] = None,
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
    from sagebench.stages.rollout import make_baseline_config, run_baseline

    config = make_baseline_config(agent_name=agent, seed=seed, max_actions=max_actions, workers=workers)
    typer.echo(run_baseline(run_dir, out, config, scene_id=scene, force=force).summary())


@app.command("rollout", cls=_defaults_from("sagebench.stages.rollout:RolloutConfig"))
def rollout_cmd(
    run_dir: Annotated[Path, typer.Option("--run", callback=existing, help="Run directory (build-scene, gen-trajectories, export-usd).")],
    out: Annotated[Path, typer.Option("--out", help="Predictions file to write (JSON Lines).")],
    policy: Annotated[str | None, typer.Option(
        help="A policy server's http(s):// URL, oracle, straight, random, or vlnce:MODULE:NAME (a VLN-CE agent class "
             "or object, run in-process).")] = None,
    split: Annotated[str | None, typer.Option("--split", autocompletion=splits,
                                              help="Only this split's episodes: train, val_seen, "
                                                               "val_unseen or test.")] = None,
    episode_id: Annotated[list[str] | None, typer.Option("--episode-id", help="Only this episode (repeat for "
                                                                               "more).")] = None,
    episodes: Annotated[int | None, typer.Option(help="Run a seeded sample of N of those episodes (default: all).")] = None,
    scene: Annotated[str | None, typer.Option("--scene", help="Only this scene's episodes (default: every scene).")] = None,
    preset: Annotated[str | None, typer.Option(autocompletion=values_of("sagebench.stages.rollout:RolloutConfig", "--preset"), help="Another benchmark's settings: vlnce (success distance 3 m, "
                                                    "VLN-CE's camera, actions and observations; the body stays the "
                                                    "one the run's maps were built for).")] = None,
    profile: Annotated[str | None, typer.Option(autocompletion=values_of("sagebench.stages.rollout:RolloutConfig", "--profile"), help="Observations: custom (--obs at --width x --height), vlnce, "
                                                     "sage or full (privileged included).")] = None,
    obs: Annotated[str | None, typer.Option(help="custom profile: images to render, rgb and/or depth, or none.")] = None,
    privileged: Annotated[str | None, typer.Option(
        help="Privileged observations to add, comma-separated: pose, gps_compass, instance.")] = None,
    width: Annotated[int | None, typer.Option(help="Image width, px (default: the profile's).")] = None,
    height: Annotated[int | None, typer.Option(help="Image height, px (default: the profile's).")] = None,
    action_space: Annotated[str | None, typer.Option("--action-space", autocompletion=values_of("sagebench.stages.rollout:RolloutConfig", "--action-space"),
                                                     help="discrete (STOP, MOVE_FORWARD, "
                                                     "TURN_LEFT, TURN_RIGHT) or continuous (v m/s, omega rad/s, stop).")] = None,
    max_steps: Annotated[int | None, typer.Option(help="Actions per episode before it is cut off.")] = None,
    policy_timeout: Annotated[float | None, typer.Option(
        help="Deadline of one policy request, s: connecting, sending and the whole reply.")] = None,
    policy_retries: Annotated[int | None, typer.Option(
        help="Retries of a policy request after a connection error, with backoff, within its deadline.")] = None,
    policy_encoding: Annotated[str | None, typer.Option(
        autocompletion=values_of("sagebench.stages.rollout:RolloutConfig", "--policy-encoding"), help="How images go to a policy server: raw, png (RGB as PNG) or json (base64, as before).")] = None,
    max_policy_failures: Annotated[int | None, typer.Option(
        help="Episodes the policy may fail (a request that failed) before the rollout stops.")] = None,
    resume: Annotated[bool, typer.Option("--resume", help="Run the episodes a killed or stopped rollout into OUT "
                                                          "did not finish, with its settings.")] = False,
    workers: Annotated[int | None, typer.Option(help="Threads stepping MuJoCo and calling the policy server.")] = None,
    threads: Annotated[int | None, typer.Option(
        help="Cores the renderer's threads use, which wait passively when idle (default: every core this process "
             "may run on).")] = None,
    batch: Annotated[int | None, typer.Option(help="Episodes stepped together (results do not depend on it).")] = None,
    seed: Annotated[int | None, typer.Option(help="Seed of the episode sample and of the random policy.")] = None,
    renderer: Annotated[str | None, typer.Option(help=RENDERER_HELP)] = None,
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

    config = make_config(policy=policy, split=split, episode_ids=tuple(episode_id or ()), episodes=episodes,
                         preset=preset, profile=profile, obs=obs, privileged=privileged, width=width, height=height,
                         action_space=action_space, max_steps=max_steps, policy_timeout=policy_timeout,
                         policy_retries=policy_retries, policy_encoding=policy_encoding,
                         max_policy_failures=max_policy_failures, workers=workers, threads=threads, batch=batch,
                         seed=seed, resume=resume, renderer=renderer)
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
