"""The run directory, declared once: every path in it, and for every command the files it reads and writes.

The pipeline derives from CONTRACT what a stage's stamp hashes (its reads), what it records as written
(its writes), which stages it waits for (those that write what it reads) and which trees the manifest
hashes; the stages take their file names from here and check their inputs with `require`. A stage that
starts reading a file must list it here, or its stamp would not notice the file change
(tests/test_run_layout.py runs every stage with nothing but the files declared here).
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from sagebench.errors import DataError

# RUN/
SCENES = "scenes"
EPISODES = "episodes"
VALIDATION = "validation"
PREVIEWS = "previews"  # beside episodes/ and validation/, which hold Parquet only: readers take each as one table
REPORTS = "reports"
BASELINES = "baselines"  # the demo's baseline predictions and scores
STAMPS = ".stamps"  # RUN/.stamps/<scene_id>/<stage>.json
MANIFEST = "manifest.json"
LOCK = ".sagebench.lock"  # held (flock) by the command writing this directory (run_lock.py); left in place after it
DATASET_CARD = "README.md"  # written by `run` with the manifest: Hugging Face configs, columns, how to load
DEMO_INPUT = "input"  # `demo`: its scene, input/demo_apartment_<seed>/
DEMO_CONFIG = "run.toml"  # `demo`: the run config of that scene, beginning with DEMO_CONFIG_HEADER
DEMO_CONFIG_HEADER = "# The demo run: `sagebench run` reads this file"

# RUN/scenes/<scene_id>/ (build-scene, then export-usd)
SCENE_FILE = "scene.json"  # the normalised scene; with the meshes it names, a loadable scene directory
TOPDOWN = "topdown.npz"
SEMANTIC_MAP = "semantic_map.json"
TOPDOWN_PNG = "topdown.png"
GAUSSIANS = "gaussians.ply"
COLLIDERS = "colliders"  # convex parts per object (STL) and COLLIDERS_INDEX
COLLIDERS_INDEX = "colliders.json"  # inside COLLIDERS
USD = "scene.usda"  # the stage's root layer (text): prims, semantics, physics
USD_GEOMETRY = "geometry.usdc"  # the arrays USD references (crate layer): Gaussians, collider meshes
USDZ = "scene.usdz"  # export-usd --usdz: USD and what it references in one package
NUREC = "gaussians.usdz"  # export-usd --gaussians nurec: the Gaussians as NVIDIA 3DGRUT's NuRec USDZ
SAGE = "sage"  # export-usd --layout sage: <scene_id>.usda (SAGE-3D's template form) + <scene_id>_collision.usd
MJCF = "scene.xml"

# RUN/episodes/<scene_id>/ (gen-trajectories): the shards, nothing else
SHARDS = "part-*.parquet"
# RUN/previews/<scene_id>/ (gen-trajectories)
PREVIEW = "paths.png"

# RUN/validation/<scene_id>/ (validate): its one shard, nothing else
VALIDATION_SHARD = "part-00000.parquet"
# RUN/reports/<scene_id>/ (validate)
REPORT = "report.json"
FRAMES = "frames"
CONTACT_SHEET = "contact_sheet.png"  # inside FRAMES

Root = Literal["source", "scene", "episodes", "previews", "validation", "reports"]
_RUN_ROOTS = {"scene": SCENES, "episodes": EPISODES, "previews": PREVIEWS, "validation": VALIDATION,
              "reports": REPORTS}


@dataclass(frozen=True)
class Place:
    """A file or directory of one scene: `rel` under `root` ("." the whole directory); with `meshes`, every
    mesh file that the scene.json in `root` names."""

    root: Root
    rel: str = "."
    meshes: bool = False


@dataclass(frozen=True)
class StageFiles:
    reads: tuple[Place, ...]
    writes: tuple[Place, ...] = ()  # nothing in the run directory: evaluate, baseline and render write elsewhere


NORMALISED_SCENE = (Place("scene", SCENE_FILE), Place("scene", meshes=True))
REPLAY_MODEL = (Place("scene", SCENE_FILE), Place("scene", SEMANTIC_MAP), Place("scene", MJCF),
                Place("scene", COLLIDERS))  # the agent's world, and its body as the map recorded it

CONTRACT: dict[str, StageFiles] = {
    "build_scene": StageFiles(
        reads=(Place("source"),),
        writes=(*NORMALISED_SCENE, Place("scene", TOPDOWN), Place("scene", SEMANTIC_MAP), Place("scene", TOPDOWN_PNG),
                Place("scene", GAUSSIANS))),
    "gen_trajectories": StageFiles(
        reads=(Place("scene", SCENE_FILE), Place("scene", TOPDOWN), Place("scene", SEMANTIC_MAP)),
        writes=(Place("episodes"), Place("previews"))),
    "export_usd": StageFiles(
        reads=(*NORMALISED_SCENE, Place("scene", GAUSSIANS), Place("scene", TOPDOWN),
               Place("scene", SEMANTIC_MAP)),  # the maps: free_floor, the agent's band
        writes=(Place("scene", COLLIDERS), Place("scene", USD_GEOMETRY), Place("scene", USD), Place("scene", USDZ),
                Place("scene", NUREC), Place("scene", SAGE), Place("scene", MJCF))),
    "validate": StageFiles(
        reads=(*REPLAY_MODEL, Place("scene", USD), Place("scene", USD_GEOMETRY), Place("scene", GAUSSIANS),
               Place("scene", TOPDOWN), Place("episodes")),
        writes=(Place("validation"), Place("reports"))),
    "evaluate": StageFiles(reads=(Place("episodes"), Place("scene", TOPDOWN), *REPLAY_MODEL)),  # the model only to replay poses
    "baseline": StageFiles(reads=(Place("episodes"), Place("scene", TOPDOWN), *REPLAY_MODEL)),  # rollout, no images
    "render": StageFiles(reads=(Place("scene", SCENE_FILE), Place("scene", GAUSSIANS))),
    "export_vlnce": StageFiles(reads=(Place("episodes"), *NORMALISED_SCENE)),  # writes its own directory
    "export_habitat": StageFiles(reads=(Place("episodes"), *NORMALISED_SCENE, Place("scene", TOPDOWN),
                                        Place("scene", SEMANTIC_MAP))),  # its own directory; the maps: view points' sight
    "export_sage": StageFiles(reads=(Place("episodes"), Place("scene", SCENE_FILE), Place("scene", SEMANTIC_MAP))),
    # writes its own directory; the map: objects to name room goals by
    "import_sage": StageFiles(reads=(Place("scene", SCENE_FILE), Place("scene", TOPDOWN), Place("scene", SEMANTIC_MAP)),
                              # and a GVLN file
                              writes=(Place("episodes"),)),
    "rollout": StageFiles(reads=(Place("episodes"), Place("scene", TOPDOWN), Place("scene", GAUSSIANS), *REPLAY_MODEL)),
    # writes its own directory; reads validate's results, evaluate's inputs and the Gaussians (views) when there
    "report": StageFiles(reads=(Place("episodes"), Place("scene", TOPDOWN), Place("scene", TOPDOWN_PNG))),
}

OUTPUT_ROOTS = tuple(sorted({_RUN_ROOTS[p.root] for s in CONTRACT.values() for p in s.writes}))

# The command that runs each stage writing into a run directory (each leaves a stamp, stamps.py).
STAGE_COMMANDS = {"build_scene": "build-scene", "gen_trajectories": "gen-trajectories", "export_usd": "export-usd",
                  "validate": "validate", "import_sage": "import-sage-episodes"}
# What each command that writes into a run directory writes there, by top-level name (run_folder.py: under
# --force the user's files may share the folder, never these names).
COMMAND_WRITES: dict[str, tuple[str, ...]] = {
    command: (*sorted({_RUN_ROOTS[p.root] for p in CONTRACT[stage].writes}), STAMPS)
    for stage, command in STAGE_COMMANDS.items()}
COMMAND_WRITES["run"] = (*OUTPUT_ROOTS, STAMPS, MANIFEST, DATASET_CARD)
COMMAND_WRITES["demo"] = (*COMMAND_WRITES["run"], BASELINES, DEMO_INPUT, DEMO_CONFIG)
# Where in a run the commands that write one file (and its sidecars) may write it: a rollout's predictions and
# their scores go to baselines/, as the demo's do, under the run's lock (run_folder.claim_output_file).
FILE_COMMAND_WRITES: dict[str, tuple[str, ...]] = {"baseline": (BASELINES,), "rollout": (BASELINES,),
                                                   "evaluate": (BASELINES,), "render": ()}

# The names directly inside one scene's directory of each output tree (besides the normalised scene's meshes and
# hidden entries); fnmatch patterns.
SCENE_NAMES = tuple(sorted({p.rel for s in CONTRACT.values() for p in s.writes if p.root == "scene" and p.rel != "."}))
TREE_NAMES = {SCENES: SCENE_NAMES, EPISODES: (SHARDS,), PREVIEWS: (PREVIEW,), VALIDATION: (VALIDATION_SHARD,),
              REPORTS: (REPORT, FRAMES)}


# what makes a scene one of the run's, for `run_scenes`: (directory under RUN, the file inside it, the stage writing it)
_FOUND_BY = {"scene": (SCENES, SCENE_FILE, "build-scene"), "episodes": (EPISODES, SHARDS, "gen-trajectories")}


def run_scenes(run_dir: Path, scene_id: str | None = None, *,
               having: Literal["scene", "episodes"] = "scene") -> list[str]:
    """The scene ids a command works on: `scene_id`, or every scene of the run (sorted), where a scene counts when
    it has its built scene (scenes/<id>/scene.json) or, with having="episodes", its episode shards
    (episodes/<id>/part-*.parquet). Otherwise a DataError naming what was looked for, the scenes found and the
    command that makes it. Every command finds its scenes here."""
    folder, pattern, stage = _FOUND_BY[having]
    root = Path(run_dir) / folder
    found = sorted(p.name for p in root.glob("*") if p.is_dir() and not p.name.startswith(".") and any(p.glob(pattern)))
    if scene_id is None and found:
        return found
    if scene_id is not None and scene_id in found:
        return [scene_id]
    raise DataError(f"no {folder}/{scene_id or '<scene_id>'}/{pattern} (scenes found: {', '.join(found) or 'none'}); "
                    f"run `sagebench {stage}` on this run first", path=run_dir)


def run_scene_dir(run_dir: Path, scene_id: str) -> Path:
    return Path(run_dir) / SCENES / scene_id


def run_episodes_dir(run_dir: Path, scene_id: str) -> Path:
    return Path(run_dir) / EPISODES / scene_id


def run_validation_dir(run_dir: Path, scene_id: str) -> Path:
    return Path(run_dir) / VALIDATION / scene_id


def run_previews_dir(run_dir: Path, scene_id: str) -> Path:
    return Path(run_dir) / PREVIEWS / scene_id


def run_reports_dir(run_dir: Path, scene_id: str) -> Path:
    return Path(run_dir) / REPORTS / scene_id


def root_dir(root: Root, run_dir: Path, scene_id: str, source: Path | None = None) -> Path:
    """The directory a Place's root names for one scene (`source`: the artist scene directory)."""
    if root == "source":
        if source is None:
            raise ValueError("the source scene directory is needed to locate a source place")
        return Path(source)
    return Path(run_dir) / _RUN_ROOTS[root] / scene_id


def producer(place: Place) -> str | None:
    """The stage that writes `place`, None for the source scene."""
    return next((name for name, s in CONTRACT.items() if place in s.writes), None)


def after(stage: str) -> tuple[str, ...]:
    """The stages that write what `stage` reads, in CONTRACT order: it runs once they have."""
    makers = {producer(p) for p in CONTRACT[stage].reads} - {None, stage}
    return tuple(name for name in CONTRACT if name in makers)


def files(place: Place, run_dir: Path, scene_id: str, source: Path | None = None) -> list[Path]:
    """The files `place` holds now, sorted; a directory's hidden entries (temporaries) are not its files."""
    root = root_dir(place.root, run_dir, scene_id, source)
    if place.meshes:
        return sorted(p for p in (root / m for m in mesh_names(root / SCENE_FILE)) if p.is_file())
    path = root / place.rel
    if path.is_dir():
        return sorted(f for f in path.rglob("*") if f.is_file()
                      and not any(part.startswith(".") for part in f.relative_to(path).parts))
    return [path] if path.is_file() else []


def stage_files(stage: str, which: Literal["reads", "writes"], run_dir: Path, scene_id: str,
                source: Path | None = None) -> list[Path]:
    """Every file a stage reads (or wrote) for one scene, in CONTRACT order."""
    return [f for p in getattr(CONTRACT[stage], which) for f in files(p, run_dir, scene_id, source)]


def mesh_names(spec_path: Path) -> list[str]:
    """The mesh files a scene.json names inside its directory, each once; none if it is unreadable (the
    scene loader refuses such a scene, and a name that leaves the directory, with a clear message)."""
    try:
        objects = json.loads(spec_path.read_text(encoding="utf-8")).get("objects", [])
        names = {o["mesh"] for o in objects if isinstance(o, dict) and isinstance(o.get("mesh"), str)}
    except (OSError, ValueError, AttributeError):
        return []
    return sorted(n for n in names if not Path(n).is_absolute() and ".." not in Path(n).parts)


def require(places: Iterable[Place], run_dir: Path, scene_id: str) -> None:
    """A DataError naming the first of `places` missing for `scene_id`, and the command that writes it
    (the source scene and the meshes scene.json names are checked by the scene loader)."""
    for place in places:
        if place.root == "source" or place.meshes:
            continue
        path = root_dir(place.root, run_dir, scene_id) / place.rel
        if not path.exists():
            raise DataError(f"missing; run `sagebench {producer(place).replace('_', '-')}` on this run first",
                            path=path)
        if path.is_dir() != (place.rel in (".", COLLIDERS)):
            raise DataError(f"is a {'directory' if path.is_dir() else 'file'} where sagebench writes a "
                            f"{'file' if path.is_dir() else 'directory'}; run `sagebench "
                            f"{producer(place).replace('_', '-')}` on this run again", path=path)
