"""Hypothesis profiles: CI draws the same examples on every run, `make explore` draws fresh ones, ten times as many.

`make test` (and so CI) runs `--hypothesis-profile=ci`: derandomized (each test's examples follow from the test
itself), no example database, a reproduction blob printed with any failure. `make explore` runs the property
tests under `explore` with a fresh seed it prints. A failing example found there becomes an explicit
`@example(...)` on its test, so CI keeps checking it.
"""

from __future__ import annotations

from hypothesis import settings

CI_EXAMPLES = 100
EXPLORE_FACTOR = 10

settings.register_profile("ci", derandomize=True, database=None, print_blob=True, deadline=None,
                          max_examples=CI_EXAMPLES)
settings.register_profile("explore", derandomize=False, database=None, print_blob=True, deadline=None,
                          max_examples=CI_EXAMPLES * EXPLORE_FACTOR)


def examples(n: int) -> int:
    """`n` examples under the CI profile, scaled with the loaded profile (explore: ten times as many)."""
    return max(1, n * settings.default.max_examples // CI_EXAMPLES)
