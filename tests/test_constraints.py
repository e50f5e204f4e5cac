"""constraints.txt pins every dependency of pyproject.toml, and the suite runs on exactly the pinned versions.

A dependency added to pyproject.toml without `make lock` fails here, so a fresh machine (CI, `make test`)
always installs the versions the tests passed with.
"""

from __future__ import annotations

import re
import tomllib
from importlib import metadata
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _pins() -> dict[str, str]:
    pins = {}
    for line in (ROOT / "constraints.txt").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            name, sep, version = line.partition("==")
            assert sep and version.strip(), f"constraints.txt: {line!r} is not an exact pin (name==version)"
            pins[_norm(name)] = version.strip()
    return pins


def _requirements(group: str | None) -> list[str]:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    reqs = project["dependencies"] if group is None else project["optional-dependencies"][group]
    return [_norm(re.match(r"[A-Za-z0-9._-]+", r).group()) for r in reqs]


def test_every_dependency_is_pinned():
    pins = _pins()
    missing = [n for g in (None, "test", "bench") for n in _requirements(g) if n not in pins]
    assert not missing, f"not in constraints.txt (run `make lock`): {missing}"


def test_the_suite_runs_on_the_pinned_versions():
    pins = _pins()
    installed = {n: metadata.version(n) for n in _requirements(None) + _requirements("test")}
    assert installed == {n: pins[n] for n in installed}, "reinstall with `make install` (pip install -c constraints.txt)"
