"""`python -m sagebench` is the `sagebench` command; `entry` is its console script."""

import sys


def entry() -> None:
    """Run the CLI; Ctrl-C while it is still being imported ends in one line too (cli.main covers the rest)."""
    try:
        from sagebench.cli import main
    except KeyboardInterrupt:
        print("error: interrupted: nothing was written", file=sys.stderr)
        sys.exit(130)
    main()


if __name__ == "__main__":
    entry()
