"""Where a command may write: every writer claims its output (checks it, then takes a lock) before it writes, and a
claim that fails, or a command that fails, leaves everything as it found it.

A folder may take a run when it is absent, empty, or holds nothing but a sagebench run: the run layout's names
(run_layout.py), a manifest.json that sagebench wrote (and the dataset card beside it), the demo's run.toml
and input/, the config being run and the scene folders it names, and hidden entries. Anything else is the user's:
the command is refused unless --force, and even with --force it is refused when one of the user's files lies
where the command writes (its top-level names, run_layout.COMMAND_WRITES), so nothing of the user's is ever
replaced or removed. Links are never a run's (a stage writing through one would write outside the run). Hidden
entries that are not sagebench's temporaries are the user's too; they never block a run and survive it
(fileio.staged_dir carries them over).

Every other output (an export's folder, a scene folder, one file and its sidecars) is claimed by the same rule
(`check_place`): never inside a sagebench run or export folder (one holding sagebench's manifest.json,
.sagebench.lock or .stamps/, links resolved first) unless it is a place in it the command declares, never an
input of the command, inside one or a folder above one, and never over an existing file that sagebench did not
write unless --force.
"""

from __future__ import annotations

import contextlib
import fnmatch
import json
import os
import stat
import threading
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from sagebench.errors import ConfigError, OutputError, SagebenchError
from sagebench.run_layout import (
    BASELINES, COMMAND_WRITES, DATASET_CARD, DEMO_CONFIG, DEMO_CONFIG_HEADER, DEMO_INPUT, FILE_COMMAND_WRITES, LOCK,
    MANIFEST, OUTPUT_ROOTS, SCENE_FILE, SCENES, STAMPS, TREE_NAMES, mesh_names,
)
from sagebench.run_lock import results_lock, run_lock

SHOWN = 3  # foreign paths named in a refusal
_claimed: dict[tuple[int, int], str] = {}  # (st_dev, st_ino) of each folder this process has claimed -> the command
_claimed_guard = threading.Lock()


@contextlib.contextmanager
def claim_run_dir(run_dir: Path, command: str, *, force: bool = False, config: Path | None = None,
                  inputs: Iterable[Path] = ()) -> Iterator[Path]:
    """Create RUN_DIR if needed, take its lock and check what it holds, for the body of `command` (a key of
    run_layout.COMMAND_WRITES); `config` and `inputs` (the run config being run and the scene folders it names)
    may lie in it. An OutputError (one line) when it is a file, cannot be created, holds the user's files
    (without `force`, or where `command` writes) or is locked by another writer. If the body raises, the lock
    file and the directories the claim created are removed again. A claim nested in another of the same
    directory in this process (`demo` starts a `run`) holds nothing more."""
    own = (config, *inputs)
    check_place(run_dir, command)  # not inside another run (the folder itself may be one)
    with _claim(Path(run_dir), command, "is a file, not a run directory: give a folder for the run",
                lambda d: check_run_dir(d, command, force=force, own=own)) as claimed:
        yield claimed


@contextlib.contextmanager
def claim_export_dir(out: Path, run_dir: Path, command: str, marker: str) -> Iterator[Path]:
    """OUT of a command that exports a run into a folder of its own (export-vlnce, export-habitat,
    export-training, export-sage), claimed as `claim_run_dir` claims a run: created if needed, locked for the body, left as found
    if the body raises. A ConfigError (--out) when OUT is the run or lies inside it (what the run's lock and
    manifest do not cover must not be written there), lies in another sagebench run or export, or holds
    anything but an earlier output of `command` (`marker` in it)."""
    out = Path(out)
    real_out, real_run = Path(os.path.realpath(out)), Path(os.path.realpath(run_dir))
    if real_out.is_relative_to(real_run):
        raise ConfigError(f"{out} lies inside the run {run_dir}: give a folder outside it", field="--out")
    check_place(out, command)  # its own lock aside: an earlier export there is this command's

    def check(d: Path) -> None:
        if not os.path.lexists(d / marker) and any(e.name != LOCK for e in _entries(d)):
            raise ConfigError(f"{d} is not empty and holds no {command} output; use a new --out", field="--out")

    with _claim(out, command, "is a file, not a folder: give a folder for the export", check) as claimed:
        yield claimed


@dataclass(frozen=True)
class Output:
    """One file a command writes: where, how to tell that sagebench wrote the file there now (so it may be
    replaced without --force; its type is checked first, a FIFO is never opened), and the option naming it."""

    path: Path
    ours: Callable[[Path], bool]
    field: str = "--out"


@contextlib.contextmanager
def claim_output_file(out: Output, command: str, *, force: bool = False, sidecars: Sequence[Output] = (),
                      inputs: Mapping[str, Path | None] | None = None) -> Iterator[Path]:
    """Claim the file `out` (and `sidecars`, written beside it or elsewhere) for the body of `command` (a key of
    run_layout.FILE_COMMAND_WRITES): each must pass `check_place` (inside a run only where the command writes,
    whose lock is then held; not one of `inputs`, option -> path), and an existing one must be empty or
    sagebench's (`ours`) unless `force` (even then a directory is refused, and links are replaced, never
    written through). OUT's results lock (run_lock.results_lock) is held for the body: a second writer of the
    same file is refused, naming the pid. Folders the claim created are removed again if the body raises."""
    outputs = (out, *sidecars)
    runs = sorted({run for o in outputs if (run := check_place(o.path, command, inputs=inputs, field=o.field))})
    with contextlib.ExitStack() as held:
        for run in runs:
            held.enter_context(_claim(run, command, "is a file", lambda d: None))
        created = _make_dirs(Path(out.path).parent)
        try:
            with results_lock(out.path):
                for o in outputs:
                    _check_replaceable(o, force)
                yield Path(out.path)
        except BaseException:
            _remove_dirs(created)
            raise


def check_scene_out(out: Path, command: str, *, ours: Callable[[Path], bool], force: bool = False,
                    inputs: Mapping[str, Path | None] | None = None) -> None:
    """A ConfigError unless the scene folder OUT, which `command` replaces whole, passes `check_place` and is
    absent, an empty folder or a scene `command` wrote (`ours`); --force replaces anything else, but never an
    input, a folder holding one or a place in a run."""
    out = Path(out)
    check_place(out, command, inputs=inputs, folder=True)
    if force or not os.path.lexists(out):
        return
    if out.is_symlink() or not out.is_dir():
        raise ConfigError("exists and is not a directory; choose another --out (or --force to replace it)",
                          path=out, field="--out")
    if _entries(out) and not ours(out):
        raise ConfigError(f"is not empty and not a scene written by `sagebench {command}`; choose another --out "
                          "(or --force to replace it)", path=out, field="--out")


def check_place(path: Path, command: str, *, inputs: Mapping[str, Path | None] | None = None,
                field: str = "--out", folder: bool = False) -> Path | None:
    """Where `command` may write `path` (a file, or with `folder` a folder it writes whole): the run it lies in
    when that is a place of the run the command declares (run_layout.COMMAND_WRITES / FILE_COMMAND_WRITES, or
    those of the command that claimed the run in this process, as `demo` writes baselines/ and input/), else
    None. A ConfigError when it lies anywhere else in a sagebench run or export (links resolved: a link into a
    run counts as inside), or is one of `inputs`, lies inside one or holds one."""
    path = Path(path)
    here = [Path(os.path.realpath(path)), Path(os.path.realpath(path.parent)) / path.name]
    for name, given in (inputs or {}).items():
        if given is None:
            continue
        source = Path(os.path.realpath(given))
        for p in here:
            how = "is" if p == source else "lies inside" if source in p.parents else "holds" if p in source.parents \
                else None
            if how:
                raise ConfigError(f"{path} {how} the input {given} ({name}); `{command}` never writes over what it "
                                  f"reads: choose another {field}", field=field)
    return [_run_around(p, path, command, field, folder) for p in here][-1]  # the last: where the rename writes


def _run_around(real: Path, path: Path, command: str, field: str, folder: bool) -> Path | None:
    """The sagebench run or export `real` lies in (None when none), when `command` declares the place there."""
    run = next((d for d in ((real, *real.parents) if folder else real.parents) if _sagebench_folder(d)), None)
    if run is None:
        return None
    rel = real.relative_to(run).parts
    if not rel or rel[0] not in (*FILE_COMMAND_WRITES.get(command, ()), *_declared(run)):
        places = ", ".join(f"{run / d}/" for d in FILE_COMMAND_WRITES.get(command, ()))
        raise ConfigError(f"{path} lies in {run}, a sagebench run or export, where `{command}` does not write"
                          f"{f' (it may write in {places})' if places else ''}: choose a path outside it",
                          field=field)
    return run


def _sagebench_folder(d: Path) -> bool:
    """Whether `d` is a sagebench run or export: it holds sagebench's manifest, a run lock or stamps."""
    return os.path.lexists(d / LOCK) or os.path.isdir(d / STAMPS) or _is_sagebench_manifest(d / MANIFEST)


def _declared(run: Path) -> tuple[str, ...]:
    """The top-level names the command that claimed `run` in this process writes (none when it did not)."""
    command = _claimed.get(_identity(run))
    return COMMAND_WRITES.get(command, ()) if command else ()


def _check_replaceable(out: Output, force: bool) -> None:
    try:
        st = os.lstat(out.path)
    except FileNotFoundError:
        return
    if stat.S_ISDIR(st.st_mode):
        raise OutputError("cannot write: Is a directory", path=out.path)  # as the rename would say, before any work
    if force or (stat.S_ISREG(st.st_mode) and (st.st_size == 0 or out.ours(Path(out.path)))):
        return
    raise OutputError(f"exists and sagebench did not write it; choose another {out.field}, or --force to replace it",
                      path=out.path)


@contextlib.contextmanager
def _claim(folder: Path, command: str, is_a_file: str, check: Callable[[Path], None]) -> Iterator[Path]:
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
                _claimed[key] = command
            try:
                yield folder
            finally:
                with _claimed_guard:
                    _claimed.pop(key, None)
    except BaseException:
        _remove_dirs(created)
        raise


def _remove_dirs(created: list[Path]) -> None:
    for d in reversed(created):
        with contextlib.suppress(OSError):
            d.rmdir()  # only if the failed command left it empty


def _identity(path: Path) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino


def check_run_dir(run_dir: Path, command: str, *, force: bool = False, own: Iterable[Path | None] = ()) -> None:
    """The refusal `claim_run_dir` makes for a folder holding the user's files (see the module docstring); `own`:
    the config being run and its inputs."""
    foreign = foreign_entries(run_dir, own=own)
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


def foreign_entries(run_dir: Path, *, own: Iterable[Path | None] = ()) -> list[str]:
    """Paths under RUN_DIR (relative, '/'-separated, a directory with a trailing '/') that are not a sagebench
    run's, sorted; hidden entries other than the run's own are left out (they are the user's, and never touched).
    `own`: files and folders that are the run's too where they lie outside its layout (the config being run,
    the scene folders it names), with the folders holding nothing else."""
    run_dir = Path(run_dir)
    out: list[str] = []
    ours_manifest = _is_sagebench_manifest(run_dir / MANIFEST)
    demo_config = _is_demo_config(run_dir / DEMO_CONFIG)
    mine = {Path(os.path.realpath(p)) for p in own if p is not None}
    for e in _entries(run_dir):
        name = e.name
        if name.startswith("."):
            if name in (LOCK, STAMPS) and e.is_symlink():
                out.append(name)
            continue
        if e.is_symlink():
            out.append(name)
        elif name not in LAYOUT_NAMES and _only(Path(e.path), mine):
            continue
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


LAYOUT_NAMES = frozenset({*TREE_NAMES, MANIFEST, DATASET_CARD, BASELINES})


def _only(path: Path, mine: set[Path]) -> bool:
    """Whether `path` is one of `mine` or a folder holding nothing but them (and hidden entries), links aside."""
    real = Path(os.path.realpath(path))
    if real in mine:
        return True
    if not any(real in m.parents for m in mine) or path.is_symlink():
        return False
    return all(not e.is_symlink() and _only(Path(e.path), mine) for e in _entries(path) if not e.name.startswith("."))


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
