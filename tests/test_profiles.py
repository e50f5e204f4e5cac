"""CI never flips a coin: every property test runs under the loaded hypothesis profile, and `make test` loads `ci`."""

from __future__ import annotations

import ast
import re
import shutil
import subprocess
from pathlib import Path

import pytest
from hypothesis import settings

from profiles import CI_EXAMPLES, EXPLORE_FACTOR, examples

TESTS = Path(__file__).parent
ROOT = TESTS.parent
OVERRIDES = {"derandomize", "database", "phases", "backend"}  # what would take a test out of its profile


def _name(node: ast.expr) -> str:
    target = node.func if isinstance(node, ast.Call) else node
    return target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")


def _property_tests() -> dict[str, list[ast.expr]]:
    """Every @given test in tests/, as "file::name" -> its decorators."""
    found = {}
    for path in sorted(TESTS.glob("test_*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef) and any(_name(d) == "given" for d in node.decorator_list):
                found[f"{path.name}::{node.name}"] = node.decorator_list
    return found


def test_every_property_test_takes_its_randomness_and_count_from_the_profile():
    tests = _property_tests()
    assert len(tests) >= 19, f"only {len(tests)} property tests found: the scan is broken"
    for name, decorators in tests.items():
        assert not any(_name(d) in ("seed", "reproduce_failure") for d in decorators), f"{name} pins its own seed"
        for d in decorators:
            if isinstance(d, ast.Call) and _name(d) == "settings":
                keys = {k.arg for k in d.keywords}
                assert not keys & OVERRIDES, f"{name} overrides {sorted(keys & OVERRIDES)} of the profile"
                count = next((k.value for k in d.keywords if k.arg == "max_examples"), None)
                assert count is None or (isinstance(count, ast.Call) and _name(count) == "examples"), (
                    f"{name}: max_examples must be examples(N), so `make explore` scales it")


def test_make_test_runs_the_ci_profile_and_make_explore_a_fresh_seed():
    makefile = (ROOT / "Makefile").read_text()
    test_recipe = re.search(r"^test:.*\n((?:\t.*\n)+)", makefile, re.M).group(1)
    explore_recipe = re.search(r"^explore:.*\n((?:\t.*\n)+)", makefile, re.M).group(1)
    assert "--hypothesis-profile=ci" in test_recipe
    assert "--hypothesis-profile=explore" in explore_recipe and "--hypothesis-seed=" in explore_recipe
    assert "make test" in (ROOT / ".ci" / "run").read_text()


def test_ci_runs_every_test_make_test_all_but_the_slow_ones_and_make_test_slow_those():
    makefile = (ROOT / "Makefile").read_text()
    recipes = {name: re.search(rf"^{name}:.*\n((?:\t.*\n)+)", makefile, re.M).group(1)
               for name in ("test", "test-slow")}
    assert recipes["test"].endswith(' -m "not slow"\n') and recipes["test-slow"].endswith(" -m slow\n")
    assert recipes["test"].replace(' -m "not slow"', "") == recipes["test-slow"].replace(" -m slow", "")
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    assert ci[-2:] == ["make test", "make test-slow"]


def test_the_ci_profile_is_derandomized_and_explore_draws_ten_times_as_many():
    ci, explore = settings.get_profile("ci"), settings.get_profile("explore")
    assert ci.derandomize and ci.database is None and ci.print_blob and ci.max_examples == CI_EXAMPLES
    assert not explore.derandomize and explore.max_examples == CI_EXAMPLES * EXPLORE_FACTOR
    assert examples(150) == 150 * settings.default.max_examples // CI_EXAMPLES
    if settings.default.derandomize:  # the run itself is under ci: the oracle property draws 150, explore 1,500
        assert examples(150) == 150


@pytest.mark.skipif(shutil.which("make") is None, reason="make is not installed")
def test_make_explore_runs_the_seed_it_prints():
    """The printed seed is the one a user replays with: `make explore EXPLORE_SEED=N`."""
    dry = subprocess.run(["make", "-n", "explore"], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    (said,) = re.findall(r"make explore: hypothesis seed (\d+)", dry)
    (used,) = re.findall(r"--hypothesis-seed=(\d+)", dry)
    assert said == used
    given = subprocess.run(["make", "-n", "explore", "EXPLORE_SEED=42"], cwd=ROOT, capture_output=True, text=True,
                           check=True).stdout
    assert "hypothesis seed 42" in given and "--hypothesis-seed=42" in given
