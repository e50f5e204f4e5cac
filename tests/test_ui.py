"""Progress off a terminal: plain lines on stderr at most every PROGRESS_EVERY_S, none when quiet."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from sagebench import ui


@pytest.fixture
def clock(monkeypatch):
    """time.monotonic as a number the test advances."""
    now = [1000.0]
    monkeypatch.setattr(ui.time, "monotonic", lambda: now[0])
    return now


@pytest.fixture
def pythons_sigint_handler():
    """Python's own SIGINT handler, as in a fresh `sagebench` process started from a terminal (a test worker
    started under `nohup` or `&` has SIGINT ignored, and interrupts_noted then installs nothing)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def test_track_prints_a_line_every_interval_off_a_terminal(clock, capsys):
    for _ in ui.track(range(6), "replaying"):
        clock[0] += 2.0  # each item takes 2 s: a line after items 3 (6 s) and 6 (12 s)
    assert capsys.readouterr().err.splitlines() == ["replaying: 3/6 in 6 s", "replaying: 6/6 in 12 s"]


def test_quick_loops_print_nothing(clock, capsys):
    assert list(ui.track(iter(range(3)), "quick")) == [0, 1, 2]
    with ui.progress(3, "quick") as update:
        update(3, "done")
    assert capsys.readouterr().err == ""


def test_progress_lines_carry_the_status(clock, capsys):
    with ui.progress(40, "rollout") as update:
        clock[0] += 7.0
        update(12, "3.1 episodes/s")
    assert capsys.readouterr().err == "rollout: 12/40 in 7 s, 3.1 episodes/s\n"


def test_quiet_hides_the_lines(clock, capsys, monkeypatch):
    monkeypatch.setattr(ui.SETTINGS, "quiet", True)
    for _ in ui.track(range(3), "hidden"):
        clock[0] += 10.0
    assert capsys.readouterr().err == ""


def test_working_ticks_while_a_silent_step_runs(capsys, monkeypatch):
    monkeypatch.setattr(ui, "PROGRESS_EVERY_S", 0.05)
    with ui.working("validate s: replaying 20 trajectories"):
        time.sleep(0.5)  # ten intervals: at least one tick however loaded the machine
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) >= 1 and all(line.startswith("validate s: replaying 20 trajectories: ") for line in lines)
    with ui.working("done at once"):
        pass
    assert capsys.readouterr().err == ""  # the ticker stops with the step


@pytest.mark.parametrize("after", ["exits 0", "fails on what it left"])
def test_a_ctrl_c_a_library_swallowed_ends_in_the_interrupt_line(after, monkeypatch, capsys, pythons_sigint_handler):
    """trimesh imports its optional parts under `except BaseException`: a Ctrl-C then is kept as an ExceptionWrapper
    and the command goes on, or fails later on a TypeError; either way the user pressed Ctrl-C and gets its line."""
    import os

    from sagebench import cli

    def command(*args, **kwargs):
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5)  # the signal arrives here
        except BaseException:  # noqa: BLE001 - what trimesh does
            pass
        if after == "fails on what it left":
            raise TypeError("unsupported operand type(s) for |: 'ExceptionWrapper' and 'NoneType'")
        raise SystemExit(0)

    monkeypatch.setattr(cli, "app", command)
    with pytest.raises(SystemExit) as done:
        cli.main(["validate", "somewhere"])
    assert done.value.code == 130
    assert capsys.readouterr().err == f"error: {cli.INTERRUPTED}\n"


def test_a_ctrl_c_noted_while_the_cli_imported_is_kept_when_the_command_starts(pythons_sigint_handler):
    """The console entry notes Ctrl-C around the CLI's imports; cli.main's own noting, inside it, keeps a note
    made there (a later command in the same process starts afresh)."""
    with ui.interrupts_noted():
        try:
            signal.raise_signal(signal.SIGINT)
        except KeyboardInterrupt:
            pass  # swallowed, as a library importing its optional parts may
        with ui.interrupts_noted():
            assert ui.interrupted()
    with ui.interrupts_noted():
        assert not ui.interrupted()


USD_IMPORT_INTERRUPTED = """
import os, signal, sys
from sagebench import ui
fired = []
def ctrl_c_as(event, args):
    if event == "import" and args[0] == sys.argv[1] and not fired:
        fired.append(args[0])
        os.kill(os.getpid(), signal.SIGINT)
sys.addaudithook(ctrl_c_as)
with ui.interrupts_noted():
    try:
        from pxr import Usd
        print("went on")
    except KeyboardInterrupt:
        print("interrupted", fired)
from pxr import Usd
print(Usd.Stage.CreateInMemory().GetRootLayer() is not None)
"""


@pytest.mark.parametrize("module", ["pxr.Gf", "pxr.Sdf", "pxr.Ts"])
def test_a_ctrl_c_while_usd_loads_its_libraries_waits_for_the_import(module, tmp_path):
    """USD loads the modules of the libraries pxr.Usd needs under a catch-all that printed a Ctrl-C there as a
    'Warning' with a Traceback (CI saw it after `run` had printed its interrupt line) and left them half-loaded;
    the Ctrl-C now ends the import first, then is raised, and USD still works after it."""
    import subprocess
    import sys

    from signals import as_from_a_terminal

    script = tmp_path / "usd_import.py"
    script.write_text(USD_IMPORT_INTERRUPTED)
    done = subprocess.run([sys.executable, str(script), module], capture_output=True, text=True, timeout=120,
                          preexec_fn=as_from_a_terminal)
    assert (done.returncode, done.stderr) == (0, "")
    assert done.stdout.splitlines() == [f"interrupted ['{module}']", "True"]


def test_quiet_reaches_the_workers_of_a_two_worker_run(tiny_scene, tmp_path):
    """`-q run --workers 2`: the spawned workers that run the stages print no progress either. A sitecustomize
    shortens every process's progress interval, so that each stage would print lines if it were not quiet."""
    from test_fuzz_safety import TOML

    (tmp_path / "site").mkdir()
    (tmp_path / "site" / "sitecustomize.py").write_text("import sagebench.ui\nsagebench.ui.PROGRESS_EVERY_S = 0.01\n")
    config = tmp_path / "t.toml"
    config.write_text(TOML.format(scene=tiny_scene, out=tmp_path / "out"))
    path = os.pathsep.join(filter(None, [str(tmp_path / "site"), os.environ.get("PYTHONPATH")]))
    proc = subprocess.run([sys.executable, "-m", "sagebench", "-q", "run", str(config), "--workers", "2"],
                          capture_output=True, text=True, timeout=600, env={**os.environ, "PYTHONPATH": path})
    assert proc.returncode == 0 and "1 scenes complete" in proc.stdout, proc.stdout + proc.stderr
    assert proc.stderr == ""
