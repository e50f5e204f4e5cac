"""Every named mutant still applies: a refactor that moves its snippet would otherwise surface only when
`make mutants` (a long job run before a release) reports NO MATCH, and the mutant's test would go unchecked."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _mutants():
    spec = importlib.util.spec_from_file_location("mutants", ROOT / "tools" / "mutants.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("mutants", module)  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module.MUTANTS


def test_every_mutants_snippet_occurs_exactly_once_and_its_tests_exist():
    mutants = _mutants()
    assert len(mutants) >= 100, f"only {len(mutants)} mutants found: the list is broken"
    assert len({m.name for m in mutants}) == len(mutants), "two mutants share a name"
    problems = []
    for m in mutants:
        count = (ROOT / m.path).read_text().count(m.old) if (ROOT / m.path).is_file() else 0
        if count != 1:
            problems.append(f"{m.name}: its snippet occurs {count} times in {m.path}")
        if m.old == m.new:
            problems.append(f"{m.name} changes nothing")
        for test in m.tests:
            path, _, name = test.partition("::")
            if not (ROOT / path).is_file():
                problems.append(f"{m.name}: {path} does not exist")
            elif name and f"def {name.split('[')[0]}(" not in (ROOT / path).read_text():
                problems.append(f"{m.name}: no test {name} in {path}")
    assert not problems, "\n".join(problems)
