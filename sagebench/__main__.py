"""`python -m sagebench` is the `sagebench` command; `entry` is its console script."""

import sys

from sagebench.ui import interrupted, interrupts_noted  # the standard library only: nothing to interrupt yet


def entry() -> None:
    """Run the CLI; Ctrl-C while it is still being imported ends in one line too (cli.main covers the rest),
    also when a library swallowed it: the imports run with the interrupt noted (CI once saw a Ctrl-C sent as
    pydantic's core library loaded ignored, and the run finished with exit 0)."""
    with interrupts_noted():
        try:
            from sagebench.cli import main
            if interrupted():
                raise KeyboardInterrupt
        except KeyboardInterrupt:
            print("error: interrupted: nothing was written", file=sys.stderr)
            sys.exit(130)
        main()


if __name__ == "__main__":
    entry()
