"""The `sagebench` command: parses options, calls one library function per command, prints.

Every SagebenchError becomes one line on stderr and exit status 2, here and nowhere else.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer

from sagebench.errors import SagebenchError
from sagebench.ui import SETTINGS

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="Turn artist-made indoor scenes into a physically executable VLN benchmark.",
)


@app.callback()
def _global(
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Hide progress bars and progress lines.")] = False,
    debug: Annotated[bool, typer.Option("--debug", help="Show the full traceback on errors.")] = False,
) -> None:
    SETTINGS.quiet = quiet
    SETTINGS.debug = debug


@app.command("synth-scene")
def synth_scene(
    out: Annotated[Path, typer.Option("--out", help="Scene directory to create (replaced if it exists).")],
    seed: Annotated[int, typer.Option(help="Layout seed; the same seed gives byte-identical files.")] = 0,
) -> None:
    """Write a procedural apartment in the artist-scene input format.

    Reads nothing. Writes OUT/scene.json and OUT/meshes/*.glb|.ply|.obj.
    """
    from sagebench.scene.synth import write_synth_scene

    spec = write_synth_scene(out, seed=seed)
    typer.echo(f"wrote {out} ({len(spec.rooms)} rooms, {len(spec.objects)} objects)")


@app.command("check-scene")
def check_scene(
    scene_dir: Annotated[Path, typer.Argument(help="Artist scene directory (scene.json + meshes).")],
) -> None:
    """Load and validate a scene directory and print a summary.

    Reads SCENE_DIR/scene.json and every mesh it names. Writes nothing.
    """
    from sagebench.scene.loader import load_scene
    from sagebench.scene.summary import summarise

    typer.echo(summarise(load_scene(scene_dir)))


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
) -> None:
    """Generate the built-in demo scene and run every pipeline stage on it.

    Reads nothing. Writes OUT/input/<scene>/ (the demo scene) and the run layout under OUT.
    """
    from sagebench.stages.demo import run_demo

    for line in run_demo(out, seed=seed):
        typer.echo(line)


@app.command("build-scene")
def build_scene_cmd(
    scene_dir: Annotated[Path, typer.Argument(help="Artist scene directory (scene.json + meshes).")],
    out: Annotated[Path, typer.Option("--out", help="Run directory; writes OUT/scenes/<scene_id>/.")],
    resolution: Annotated[float | None, typer.Option(help="Grid cell side, m.")] = None,
    band_min: Annotated[float | None, typer.Option(help="Lowest blocking height above the floor, m.")] = None,
    band_max: Annotated[float | None, typer.Option(help="Highest blocking height above the floor, m.")] = None,
    sample_density: Annotated[float | None, typer.Option(help="Footprint surface samples per m^2.")] = None,
    wall_gap: Annotated[float | None, typer.Option(help="Join room floors across walls up to this thick, m.")] = None,
    agent_radius: Annotated[float | None, typer.Option(help="Agent radius for the navigable map, m.")] = None,
    seed: Annotated[int | None, typer.Option(help="Seed of the footprint sampling.")] = None,
) -> None:
    """Build the semantic top-down map and the height-band occupancy of one scene.

    Reads SCENE_DIR/scene.json and its meshes.

    Writes OUT/scenes/<scene_id>/: scene.json and meshes/ (normalised), topdown.npz,
    semantic_map.json and topdown.png.

    Defaults: resolution 0.05, band-min 0.05, band-max 1.2, sample-density 400,
    wall-gap 0.3, agent-radius 0.2, seed 0.
    """
    from sagebench.stages.build_scene import build_scene, make_config

    config = make_config(resolution=resolution, band_min=band_min, band_max=band_max, sample_density=sample_density,
                         wall_gap=wall_gap, agent_radius=agent_radius, seed=seed)
    typer.echo(build_scene(scene_dir, out, config).summary())


def main(argv: list[str] | None = None) -> None:
    """Console entry point: the one place where errors become exit status 2."""
    try:
        app(args=argv, prog_name="sagebench")
    except SagebenchError as err:
        if SETTINGS.debug:
            raise
        print(f"error: {err}", file=sys.stderr)
        sys.exit(err.exit_code)

