"""Starting a command under test as a terminal would, for the Ctrl-C tests."""

from __future__ import annotations

import signal


def as_from_a_terminal() -> None:
    """A suite started in the background by a non-interactive shell (`make test &`, `nohup ... &`) runs with
    SIGINT ignored, as POSIX shells start such jobs; the child inherits SIG_IGN through exec, Python then
    installs no KeyboardInterrupt handler, and the command ignores the signal, finishes and exits 0. Give
    the child SIGINT's default, as a command started from a terminal has (a Popen preexec_fn)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
