"""sagebench/settings/shared.py: the agent's body and camera are declared there once, checked, and re-typed nowhere else."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

import sagebench
from sagebench.errors import ConfigError
from sagebench.settings.build_scene import BuildSceneConfig
from sagebench.settings.option import from_options
from sagebench.settings.shared import AgentConfig, CameraConfig

ROOT = Path(sagebench.__file__).parent
DECLARED_IN = ROOT / "settings" / "shared.py"
FACTS = {0.2, 1.2, 0.05}  # the default radius, height (and camera height) and clearance, m
# names under which a module would re-declare them: constants, fields, parameters
NAMED = re.compile(r"radius|height|clearance|band|agent|robot|floor", re.IGNORECASE)


def _literals(node: ast.AST | None) -> set[float]:
    """The numbers a default or constant is made of (a number, or a tuple / list of them)."""
    if isinstance(node, ast.Constant) and isinstance(node.value, int | float) and not isinstance(node.value, bool):
        return {float(node.value)}
    if isinstance(node, ast.Tuple | ast.List):
        return set().union(*(_literals(e) for e in node.elts))
    if isinstance(node, ast.Call) and getattr(node.func, "id", "") == "Field":  # Field(default=...)
        return set().union(*(_literals(k.value) for k in node.keywords if k.arg == "default"))
    return set()


def restated_facts(source: str) -> list[str]:
    """Where `source` binds a name like the agent's body or band to one of its default values: a constant or a
    field (`AGENT_BAND = (0.05, 1.2)`, `band_max: float = Field(default=1.2)`) or a parameter's default
    (`snap_radius: float = 0.20`)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Assign | ast.AnnAssign):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names = [t.id if isinstance(t, ast.Name) else getattr(t, "attr", "") for t in targets]
            pairs = [(n, node.value) for n in names]
        elif isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            args = node.args
            positional = args.posonlyargs + args.args
            pairs = [(a.arg, d) for a, d in zip(positional[len(positional) - len(args.defaults):], args.defaults)]
            pairs += [(a.arg, d) for a, d in zip(args.kwonlyargs, args.kw_defaults)]
        else:
            continue
        for name, value in pairs:
            if NAMED.search(name) and _literals(value) & FACTS:
                found.append(f"line {node.lineno}: {name}")
    return found


def test_the_agents_body_and_band_are_declared_in_settings_shared_only():
    restated = {str(p.relative_to(ROOT)): hits for p in sorted(ROOT.rglob("*.py")) if p != DECLARED_IN
                for hits in [restated_facts(p.read_text(encoding="utf-8"))] if hits}
    assert restated == {}
    assert restated_facts(DECLARED_IN.read_text(encoding="utf-8"))  # the check sees the declarations themselves


@pytest.mark.parametrize("source, hit", [
    ("AGENT_BAND = (0.05, 1.2)", "line 1: AGENT_BAND"),
    ("FLOOR_CLEARANCE = 0.05  # m", "line 1: FLOOR_CLEARANCE"),
    ("class C:\n    band_max: float = Field(default=1.2, gt=0)", "line 2: band_max"),
    ("def f(x, *, snap_radius: float = 0.20): pass", "line 1: snap_radius"),
    ("def agent_camera(x, camera_height=1.2): pass", "line 1: camera_height"),
    ("ROBOT_R = 0.2  # the connectivity check's robot radius, m", "line 1: ROBOT_R"),
])
def test_the_check_finds_each_way_a_module_restated_them_before(source, hit):
    """The four places issue 29 found (topdown/config.py, quality.AGENT_BAND, physics.FLOOR_CLEARANCE, the
    defaults of snap_radius and camera_height) and the demo generator's robot, in the forms they took."""
    assert restated_facts(source) == [hit]


def test_unrelated_numbers_and_names_pass():
    assert restated_facts("resolution: float = Field(default=0.05)\nwidth = 1.2\ndef f(step=0.05): pass") == []


def test_the_band_is_the_body_and_must_have_a_top_above_its_bottom():
    agent = AgentConfig()
    assert agent.band == (agent.clearance, agent.height) == (0.05, 1.2) and agent.radius == 0.2
    assert CameraConfig().height == 1.2 and CameraConfig().hfov_deg == 90.0
    with pytest.raises(ValueError, match=r"0\.5 must be above the band's bottom, clearance \(0\.6\)"):
        AgentConfig(clearance=0.6, height=0.5)
    with pytest.raises(ConfigError, match=r"^--band-max: 0\.04 must be above the band's bottom, clearance \(0\.05\)$"):
        from_options(BuildSceneConfig, {"--band-max": 0.04})
    given = {"--band-min": 0.1, "--band-max": 1.8, "--agent-radius": 0.3}
    assert from_options(BuildSceneConfig, given).agent == AgentConfig(radius=0.3, clearance=0.1,
                                                                                            height=1.8)
