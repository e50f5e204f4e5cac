"""Option defaults have one source: --help shows each settings model's defaults, the option blocks of the README
and docs/ match --help, and a bad option value is an error naming the option as typed."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest
from pydantic import BaseModel

from sagebench.config import from_options
from sagebench.errors import ConfigError

ROOT = Path(__file__).resolve().parent.parent
COMMANDS = {  # command -> (stage module, settings model[, its options table when not OPTIONS])
    "build-scene": ("sagebench.stages.build_scene", "BuildSceneConfig"),
    "gen-trajectories": ("sagebench.stages.gen_trajectories", "GenTrajectoriesConfig"),
    "render": ("sagebench.stages.render", "RenderConfig"),
    "export-usd": ("sagebench.stages.export_usd", "ExportConfig"),
    "validate": ("sagebench.stages.validate", "ValidateConfig"),
    "evaluate": ("sagebench.stages.evaluate", "EvaluateConfig"),
    "baseline": ("sagebench.stages.rollout", "BaselineConfig", "BASELINE_OPTIONS"),
    "rollout": ("sagebench.stages.rollout", "RolloutConfig"),
    "import-interiorgs": ("sagebench.stages.import_interiorgs", "InteriorGSConfig"),
    "import-sage-episodes": ("sagebench.stages.import_sage", "SageImportConfig"),
}


def _settings(command: str) -> tuple[type[BaseModel], dict[str, str]]:
    module = importlib.import_module(COMMANDS[command][0])
    return getattr(module, COMMANDS[command][1]), getattr(module, (*COMMANDS[command], "OPTIONS")[2])


def _default(model: type[BaseModel], path: str) -> object:
    value: object = model()  # the model's own defaults, read through an instance
    for part in path.split("."):
        value = getattr(value, part)
    return value


def _shown(value: object) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def _help(run_cli, monkeypatch, command: str) -> dict[str, str]:
    """--help of COMMAND as option -> its help text, each on one line (click's help at a very wide terminal)."""
    import typer.main

    from sagebench.cli import app

    code, out, _ = run_cli(command, "--help")
    assert code == 0 and f"sagebench {command}" in out
    group = typer.main.get_command(app)
    root = typer.Context(group, info_name="sagebench", terminal_width=10_000, max_content_width=10_000)
    text = group.commands[command].get_help(typer.Context(group.commands[command], info_name=command, parent=root))
    return dict(re.findall(r"^  (--[a-z-]+)(?:, -\w)?(?: <[\w\[\]|]+>)?\s{2,}(.*?)\s*$", text, re.MULTILINE))


@pytest.mark.parametrize("command", list(COMMANDS))
def test_help_shows_the_models_defaults(command, run_cli, monkeypatch):
    model, options = _settings(command)
    shown = _help(run_cli, monkeypatch, command)
    assert set(options) <= set(shown), "OPTIONS names an option the command does not have"
    for option, path in options.items():
        value = _default(model, path)
        if value in (None, ()) or isinstance(value, bool) or "[required]" in shown[option]:
            assert "(default " not in shown[option], option
        else:
            assert shown[option].endswith(f"(default {_shown(value)})."), (option, shown[option])


def test_no_default_is_typed_into_the_cli():
    # "(default 200)" written by hand would drift from the model; "(default: every scene)" describes behaviour
    text = (ROOT / "sagebench" / "cli.py").read_text()
    assert re.findall(r"\(default (?!X\)|\{)[^:)]*\)", text) == []


def _doc_blocks() -> dict[str, list[tuple[str, str]]]:
    """command -> the [--option VALUE] pairs of the usage blocks (```bash ... sagebench COMMAND ...) in the README
    and the topic pages (docs/cli.md is --help itself)."""
    found: dict[str, list[tuple[str, str]]] = {}
    pages = [ROOT / "README.md", *(p for p in sorted((ROOT / "docs").glob("*.md")) if p.name != "cli.md")]
    for block in re.findall(r"```bash\n(.*?)```", "".join(p.read_text() for p in pages), re.DOTALL):
        for usage in re.split(r"\n(?=sagebench )", block):
            m = re.match(r"sagebench ([a-z-]+)", usage)
            if m and m.group(1) in COMMANDS:
                found.setdefault(m.group(1), []).extend(re.findall(r"\[(--[a-z-]+)(?: ([^\]\s]+))?\]", usage))
    return found


def test_doc_option_blocks_match_help(run_cli, monkeypatch):
    blocks = _doc_blocks()
    assert {"build-scene", "gen-trajectories", "export-usd", "validate"} <= set(blocks)
    for command, pairs in blocks.items():
        model, options = _settings(command)
        shown = _help(run_cli, monkeypatch, command)
        for option, value in pairs:
            assert option in shown, f"docs: {command} has no {option}"
            if option in options and re.fullmatch(r"-?[0-9.]+", value):  # a number is the default; N, ID placeholders
                default = _default(model, options[option])
                assert float(value) == default, f"docs: {command} {option} {value}, but its default is {default}"


def _nested(path: str, value: object) -> dict:
    first, *rest = path.split(".")
    return {first: _nested(".".join(rest), value) if rest else value}


@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_bad_value_names_the_option(command):
    model, options = _settings(command)
    checked = 0
    for option, path in options.items():
        if isinstance(_default(model, path), str | type(None)):
            continue  # a free string (a URL, a model name) has no bad value of this kind
        with pytest.raises(ConfigError) as err:
            from_options(model, _nested(path, "not a value"), options)
        assert str(err.value).startswith(f"{option}: "), str(err.value)
        checked += 1
    assert checked
