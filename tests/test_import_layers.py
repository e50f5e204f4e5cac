"""Imports point down: cli -> pipeline, report -> stages -> library packages -> scene/fileio/errors/settings.

Every `import` in the package (module level, inside functions and under TYPE_CHECKING alike) is read with
`ast`; a module may import only from its own layer or below, no stage imports another stage, and the
packages' import graph has no cycle (so no two packages import each other).
"""

from __future__ import annotations

import ast
from pathlib import Path

import sagebench

ROOT = Path(sagebench.__file__).parent

# Top-level modules and packages of sagebench by layer; a package not named here counts as a library package.
LAYERS = {
    "cli": 4, "cli_examples": 4, "cli_settings": 4, "__main__": 4,
    "schemas": 4,  # schemas gathers every model, the run config's included
    "pipeline": 3,
    "report": 3,  # reads finished outputs through the stages' readers (evaluate's scores, render's views)
    "stages": 2,
    "scene": 0, "fileio": 0, "input_files": 0, "errors": 0, "settings": 0, "ui": 0, "run_layout": 0, "http_client": 0,
    "threads": 0,  # the standard library only; the package's __init__ sets the process defaults with it
    "__init__": 0,
}
LIBRARY = 1
NAMES = {4: "cli", 3: "pipeline", 2: "stages", 1: "library", 0: "base"}


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT.parent).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def unit(module: str) -> str:
    """The top-level module or package of `sagebench.a.b` ("a"); "__init__" for the package itself."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def layer(module: str) -> int:
    return LAYERS.get(unit(module), LIBRARY)


def imports(here: str, source: str, modules: set[str], *, is_package: bool = False) -> set[str]:
    """The sagebench modules that module `here` (source text) imports anywhere in it; `from pkg import mod`
    counts as pkg.mod, relative imports are resolved."""
    package = here if is_package else here.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.split(".")[0] == "sagebench")
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, *([base] if base else [])])
            if base.split(".")[0] != "sagebench":
                continue
            for a in node.names:
                out.add(f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base)
    return out - {here}


def import_graph() -> dict[str, set[str]]:
    paths = sorted(ROOT.rglob("*.py"))
    modules = {module_name(p) for p in paths}
    return {module_name(p): imports(module_name(p), p.read_text(encoding="utf-8"), modules,
                                    is_package=p.name == "__init__.py") for p in paths}


def violations(graph: dict[str, set[str]]) -> list[str]:
    """Every upward import, stage-to-stage import and package cycle in a module import graph."""
    out = []
    for src, dsts in sorted(graph.items()):
        for dst in sorted(dsts):
            if layer(dst) > layer(src):
                out.append(f"{src} ({NAMES[layer(src)]}) imports {dst} ({NAMES[layer(dst)]}), a layer above it")
            elif unit(src) == unit(dst) == "stages":
                out.append(f"stage {src} imports stage {dst}")
    packages: dict[str, set[str]] = {}
    for src, dsts in graph.items():
        packages.setdefault(unit(src), set()).update(unit(d) for d in dsts if unit(d) != unit(src))
    out += [f"package cycle: {' -> '.join(c)}" for c in cycles(packages)]
    return out


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One cycle through each strongly connected group of more than one node (depth-first search)."""
    found, done = [], set()
    for start in sorted(graph):
        if start in done:
            continue
        stack, path, on_path = [(start, iter(sorted(graph.get(start, ()))))], [start], {start}
        while stack:
            node, children = stack[-1]
            child = next(children, None)
            if child is None:
                stack.pop()
                path.pop()
                on_path.discard(node)
                done.add(node)
            elif child in on_path:
                found.append(path[path.index(child):] + [child])
            elif child not in done:
                stack.append((child, iter(sorted(graph.get(child, ())))))
                path.append(child)
                on_path.add(child)
    return found


def test_imports_point_down_and_packages_form_no_cycle():
    graph = import_graph()
    assert {"sagebench.cli", "sagebench.pipeline.run", "sagebench.stages.validate", "sagebench.topdown.builder",
            "sagebench.render.splat_render"} <= graph.keys()
    assert "sagebench.render.camera" in graph["sagebench.splats.scene"]  # edges are really read
    found = violations(graph)
    assert not found, "\n".join(found)


def test_each_kind_of_bad_import_is_reported():
    graph = {
        "sagebench.topdown.render_png": {"sagebench.stages.build_scene"},  # library -> stage
        "sagebench.stages.evaluate": {"sagebench.stages.validate", "sagebench.pipeline.run"},  # stage -> stage, up
        "sagebench.stages.validate": set(),
        "sagebench.stages.build_scene": set(),
        "sagebench.pipeline.run": set(),
        "sagebench.render.camera": {"sagebench.splats.ply"},
        "sagebench.splats.ply": {"sagebench.replay.alignment"},
        "sagebench.replay.alignment": {"sagebench.render.camera"},  # render -> splats -> replay -> render
        "sagebench.scene.model": {"sagebench.errors"},  # fine: base within base
        "sagebench.errors": set(),
    }
    found = violations(graph)
    assert len(found) == 4, found
    assert any("render_png" in v and "a layer above" in v for v in found)
    assert any("stage sagebench.stages.evaluate imports stage sagebench.stages.validate" == v for v in found)
    assert any("evaluate" in v and "pipeline.run" in v for v in found)
    assert any(v.startswith("package cycle:") and {"render", "splats", "replay"} <= set(v.split()) for v in found)


def test_relative_lazy_and_type_checking_imports_are_read():
    modules = {"sagebench.render", "sagebench.render.camera", "sagebench.render.sh", "sagebench.fileio",
               "sagebench.stages", "sagebench.stages.validate"}
    source = ("from typing import TYPE_CHECKING\nfrom . import sh\nfrom .camera import Camera\n"
              "from sagebench import fileio, __version__\nimport numpy\n"
              "if TYPE_CHECKING:\n    from ..stages.validate import X\n"
              "def f():\n    import sagebench.pipeline.run\n")
    assert imports("sagebench.render.x", source, modules) == {
        "sagebench.render.sh", "sagebench.render.camera", "sagebench.fileio", "sagebench",
        "sagebench.stages.validate", "sagebench.pipeline.run"}


MAX_STAGE_FUNCTION_LINES = 40  # a stage reads its inputs, calls the library, writes its outputs


def long_functions(source: str, limit: int) -> list[tuple[str, int]]:
    """(name, lines) of each function or method in `source` longer than `limit` lines, from its first decorator
    to its last line, docstring included."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            first = min([node.lineno, *(d.lineno for d in node.decorator_list)])
            if node.end_lineno - first + 1 > limit:
                out.append((node.name, node.end_lineno - first + 1))
    return out


def test_stages_are_thin_no_stage_function_is_longer_than_40_lines():
    found = [f"sagebench/stages/{p.name}: {name} is {n} lines" for p in sorted((ROOT / "stages").glob("*.py"))
             for name, n in long_functions(p.read_text(encoding="utf-8"), MAX_STAGE_FUNCTION_LINES)]
    assert len(list((ROOT / "stages").glob("*.py"))) >= 9  # the stage modules are really read
    assert not found, "\n".join(found)


BUILD_STEP_MODULES = ("builder", "footprints", "occupancy", "passages", "regions")  # sagebench/topdown/builder.py's steps


def test_the_map_builders_steps_are_short_enough_to_read_alone():
    """build-scene's maps are made in named steps (topdown/builder.py's docstring), none over 40 lines, so a newcomer
    finds each step and tests it alone instead of reading one function that does them all."""
    found = [f"sagebench/topdown/{m}.py: {name} is {n} lines" for m in BUILD_STEP_MODULES
             for name, n in long_functions((ROOT / "topdown" / f"{m}.py").read_text(encoding="utf-8"), 40)]
    assert not found, "\n".join(found)


def test_a_long_function_or_method_is_reported_with_its_length():
    def indented(lines: int, depth: int) -> str:
        return "".join(" " * depth + "x = 1\n" for _ in range(lines))

    source = (f'def fits():\n    """Forty lines with its def and docstring."""\n{indented(38, 4)}'
              f"\n\nclass A:\n    @staticmethod\n    def too_long():\n{indented(39, 8)}"
              f"\n    async def also():\n{indented(80, 8)}")
    assert long_functions(source, 40) == [("too_long", 41), ("also", 81)]  # the decorator counts
    assert long_functions(source, 39) == [("fits", 40), ("too_long", 41), ("also", 81)]
