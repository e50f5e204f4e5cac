"""`python -m sagebench` is the `sagebench` command."""

from sagebench.cli import main

main()
