"""Which folders a command may write a run into: every writer claims the folder (checks it, then takes the run
lock) before it writes, and a claim that fails, or a command that fails, leaves the folder as it found it.

A folder may take a run when it is absent, empty, or holds nothing but a sagebench run: the run layout's names
(run_layout.py), a manifest.json that sagebench wrote (and the dataset card beside it), the demo's run.toml
and input/, and hidden entries. Anything else is the user's: the command is refused unless --force, and even
with --force it is refused when one of the user's files lies where the command writes (its top-level names,
run_layout.COMMAND_WRITES), so nothing of the user's is ever replaced or removed. Links are never a run's
(a stage writing through one would write outside the run). Hidden entries that are not sagebench's
temporaries are the user's too; they never block a run and survive it (fileio.staged_dir carries them over).
"""

from __future__ import annotations

import contextlib
import fnmatch
import json
import os
import stat
import threading
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from sagebench.errors import ConfigError, OutputError, SagebenchError
from sagebench.run_layout import (
    BASELINES, COMMAND_WRITES, DATASET_CARD, DEMO_CONFIG, DEMO_CONFIG_HEADER, DEMO_INPUT, LOCK,
    MANIFEST, OUTPUT_ROOTS, SCENE_FILE, SCENES, STAMPS, TREE_NAMES, mesh_names,
)
from sagebench.run_lock import run_lock

SHOWN = 3  # foreign paths named in a refusal
_claimed: set[tuple[int, int]] = set()  # (st_dev, st_ino) of the run directories this process has claimed
_claimed_guard = threading.Lock()


@contextlib.contextmanager
def claim_run_dir(run_dir: Path, command: str, *, force: bool = False) -> Iterator[Path]:
    """Create RUN_DIR if needed, take its lock and check what it holds, for the body of `command` (a key of
    run_layout.COMMAND_WRITES). An OutputError (one line) when it is a file, cannot be created, holds the
    user's files (without `force`, or where `command` writes) or is locked by another writer. If the body
    raises, the lock file and the directories the claim created are removed again. A claim nested in another of
    the same directory in this process (`demo` starts a `run`) holds nothing more."""
    with _claim(Path(run_dir), "is a file, not a run directory: give a folder for the run",
                lambda d: check_run_dir(d, command, force=force)) as claimed:
        yield claimed


@contextlib.contextmanager
def claim_export_dir(out: Path, run_dir: Path, command: str, marker: str) -> Iterator[Path]:
    """OUT of a command that exports a run into a folder of its own (export-vlnce, export-training), claimed as
    `claim_run_dir` claims a run: created if needed, locked for the body, left as found if the body raises. A
    ConfigError (--out) when OUT is the run or lies inside it (what the run's lock and manifest do not cover
    must not be written there), or holds anything but an earlier output of `command` (`marker` in it)."""
    out = Path(out)
    real_out, real_run = Path(os.path.realpath(out)), Path(os.path.realpath(run_dir))
    if real_out.is_relative_to(real_run):
        raise ConfigError(f"{out} lies inside the run {run_dir}: give a folder outside it", field="--out")

    def check(d: Path) -> None:
        if not os.path.lexists(d / marker) and any(e.name != LOCK for e in _entries(d)):
            raise ConfigError(f"{d} is not empty and holds no {command} output; use a new --out", field="--out")

    with _claim(out, "is a file, not a folder: give a folder for the export", check) as claimed:
        yield claimed


@contextlib.contextmanager
def _claim(folder: Path, is_a_file: str, check: Callable[[Path], None]) -> Iterator[Path]:
    if os.path.lexists(folder) and not folder.is_dir():
        raise OutputError(is_a_file, path=folder)
    if _identity(folder) in _claimed:
        yield folder
        return
    created = _make_dirs(folder)
    key = _identity(folder)
    try:
        with run_lock(folder):
            if not created:
                check(folder)
            with _claimed_guard:
                _claimed.add(key)
            try:
                yield folder
            finally:
                with _claimed_guard:
                    _claimed.discard(key)
    except BaseException:
        for d in reversed(created):
            with contextlib.suppress(OSError):
                d.rmdir()  # only if the failed command left it empty
        raise


def _identity(path: Path) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino


def check_run_dir(run_dir: Path, command: str, *, force: bool = False) -> None:
    """The refusal `claim_run_dir` makes for a folder holding the user's files (see the module docstring)."""
    foreign = foreign_entries(run_dir)
    if not foreign:
        return
    if not force:
        raise OutputError(f"holds files that are not a sagebench run's ({_some(foreign)}): give an empty or new "
                          "folder, or --force to write the run beside them (they are never changed)", path=run_dir)
    written = COMMAND_WRITES[command]
    clash = [f for f in foreign if f.split("/")[0] in written]
    if clash:
        one = len(clash) == 1
        raise OutputError(f"{_some(clash)} {'is' if one else 'are'} not a sagebench run's and {'lies' if one else 'lie'} "
                          f"where `{command}` writes; even with --force it never replaces {'it' if one else 'them'}: "
                          "move it elsewhere or choose another folder", path=run_dir)


def check_scenes_apart(run_dir: Path, scene_dirs: Iterable[Path], *, path: Path | None = None,
                       out_field: str = "--out", scenes_field: str = "SCENE_DIR") -> None:
    """A ConfigError unless the run directory lies outside every input scene (its outputs would change the
    scene's inputs every run) and no input scene lies where the run writes (a stage would replace it)."""
    out = Path(os.path.abspath(run_dir))
    written = [out / d for d in (*OUTPUT_ROOTS, STAMPS)]
    for scene_dir in sorted(scene_dirs):
        scene = Path(os.path.abspath(scene_dir))
        if out == scene or scene in out.parents:
            raise ConfigError(f"the run directory {run_dir} is inside the input scene {scene_dir}; "
                              f"put {out_field} outside every scene directory", path=path, field=out_field)
        if any(w == scene or w in scene.parents for w in written):
            raise ConfigError(f"the input scene {scene_dir} is inside {run_dir}'s output folders "
                              f"({', '.join(d + '/' for d in (*OUTPUT_ROOTS, STAMPS))}); move it elsewhere",
                              path=path, field=scenes_field)


def foreign_entries(run_dir: Path) -> list[str]:
    """Paths under RUN_DIR (relative, '/'-separated, a directory with a trailing '/') that are not a sagebench
    run's, sorted; hidden entries other than the run's own are left out (they are the user's, and never touched)."""
    run_dir = Path(run_dir)
    out: list[str] = []
    ours_manifest = _is_sagebench_manifest(run_dir / MANIFEST)
    demo_config = _is_demo_config(run_dir / DEMO_CONFIG)
    for e in _entries(run_dir):
        name = e.name
        if name.startswith("."):
            if name in (LOCK, STAMPS) and e.is_symlink():
                out.append(name)
            continue
        if e.is_symlink():
            out.append(name)
        elif name == MANIFEST:
            out += [] if ours_manifest else [name]
        elif name == DATASET_CARD:
            out += [] if ours_manifest and e.is_file() else [name]
        elif name == DEMO_CONFIG:
            out += [] if demo_config else [name]
        elif name == DEMO_INPUT:
            out += [] if demo_config and e.is_dir() else [name + "/"]
        elif name == BASELINES:
            out += [] if e.is_dir() else [name]
        elif name in TREE_NAMES and e.is_dir():
            out += _tree_foreign(run_dir, name)
        else:
            out.append(name + ("/" if e.is_dir() else ""))
    return sorted(out)


def _tree_foreign(run_dir: Path, tree: str) -> list[str]:
    """What under RUN/<tree>/<scene_id>/ no stage wrote: a scene directory's direct entries must be the tree's
    names (TREE_NAMES) or, in scenes/, the normalised scene's meshes."""
    out = []
    for scene in _entries(run_dir / tree):
        rel = f"{tree}/{scene.name}"
        if scene.name.startswith("."):
            continue
        if scene.is_symlink() or not scene.is_dir():
            out.append(rel)
            continue
        names = {e.name: e for e in _entries(Path(scene.path)) if not e.name.startswith(".")}
        meshes = _mesh_tops(Path(scene.path)) if tree == SCENES else set()
        for name, e in sorted(names.items()):
            if e.is_symlink() or not (any(fnmatch.fnmatchcase(name, p) for p in TREE_NAMES[tree]) or name in meshes):
                out.append(f"{rel}/{name}" + ("/" if e.is_dir() and not e.is_symlink() else ""))
    return out


def _mesh_tops(scene_dir: Path) -> set[str]:
    """The first path component of every mesh the scene's scene.json names (every name, when it is unreadable:
    the stage reading it then says what is wrong)."""
    if not (scene_dir / SCENE_FILE).is_file():
        return set()
    from sagebench.scene.loader import mesh_files

    names = mesh_names(scene_dir / SCENE_FILE)
    if not names:
        return {e.name for e in _entries(scene_dir)}
    tops = set()
    for name in names:
        with contextlib.suppress(SagebenchError):  # a .gltf's buffers too; a broken one is the stage's to report
            tops.update(f.split("/")[0] for f in mesh_files(scene_dir, name, scene_dir / SCENE_FILE, "objects.mesh"))
        tops.add(name.split("/")[0])
    return tops


def _entries(d: Path) -> list[os.DirEntry]:
    try:
        with os.scandir(d) as it:
            return sorted(it, key=lambda e: e.name)
    except (FileNotFoundError, NotADirectoryError):
        return []
    except OSError as err:
        raise OutputError(f"cannot list: {err.strerror or err}", path=d) from None


def _is_sagebench_manifest(path: Path) -> bool:
    try:
        if not stat.S_ISREG(os.lstat(path).st_mode):
            return False
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return False
    return isinstance(doc, dict) and "sagebench_version" in doc and isinstance(doc.get("files"), dict)


def _is_demo_config(path: Path) -> bool:
    try:
        if not stat.S_ISREG(os.lstat(path).st_mode):
            return False
        with path.open("rb") as fh:
            return fh.read(len(DEMO_CONFIG_HEADER)) == DEMO_CONFIG_HEADER.encode()
    except OSError:
        return False


def _make_dirs(run_dir: Path) -> list[Path]:
    """Create RUN_DIR and its missing parents; the ones created, outermost first (a one-line error if it cannot)."""
    missing = []
    p = Path(os.path.abspath(run_dir))
    while not os.path.lexists(p):
        missing.append(p)
        p = p.parent
    created = []
    try:
        for d in reversed(missing):
            d.mkdir()
            created.append(d)
    except OSError as err:
        for d in reversed(created):
            with contextlib.suppress(OSError):
                d.rmdir()
        raise OutputError(f"cannot create: {err.strerror or err}", path=err.filename or run_dir) from None
    return created


def _some(paths: list[str]) -> str:
    more = len(paths) - SHOWN
    return ", ".join(paths[:SHOWN]) + (f" and {more} more" if more > 0 else "")
