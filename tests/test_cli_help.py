"""Each setting is declared once, in its settings model (sagebench/settings/): every option of a command is either
a field's option, whose --help is that field's description with the field's default, or one of the few options
that are not settings (what a command reads and writes); the option blocks of the README and docs/ match
--help, and a bad option value is an error naming the option as typed."""

from __future__ import annotations

import importlib
import re
from pathlib import Path
from typing import Literal, get_origin

import pytest
from pydantic import BaseModel

from sagebench.errors import ConfigError
from sagebench.settings.option import Setting, from_options, settings_of

ROOT = Path(__file__).resolve().parent.parent
SETTINGS = {  # command -> the module and model of its settings
    "build-scene": ("sagebench.settings.build_scene", "BuildSceneConfig"),
    "gen-trajectories": ("sagebench.settings.gen_trajectories", "GenTrajectoriesConfig"),
    "render": ("sagebench.settings.render", "RenderConfig"),
    "export-usd": ("sagebench.settings.export_usd", "ExportConfig"),
    "validate": ("sagebench.settings.validate", "ValidateConfig"),
    "evaluate": ("sagebench.settings.evaluate", "EvaluateConfig"),
    "baseline": ("sagebench.settings.baseline", "BaselineConfig"),
    "rollout": ("sagebench.settings.rollout", "RolloutConfig"),
    "import-interiorgs": ("sagebench.settings.import_interiorgs", "InteriorGSConfig"),
    "import-sage-episodes": ("sagebench.settings.import_sage_episodes", "SageImportConfig"),
    "export-training": ("sagebench.settings.export_training", "TrainingExportConfig"),
    "export-vlnce": ("sagebench.settings.export_vlnce", "VlnceExportConfig"),
    "report": ("sagebench.settings.report", "ReportConfig"),
    "run": ("sagebench.settings.run", "RunConfig"),
}
# The options that are not settings: what a command reads and writes, which scene or split it works on, --force,
# the generators' seeds (they name what is made) and verify's workers; everything else is a field's option.
NOT_SETTINGS = {
    "synth-scene": {"--out", "--seed", "--furniture", "--force"},
    "check-scene": set(),
    "schemas": {"--out"},
    "demo": {"--out", "--seed", "--force"},
    "import-interiorgs": {"--out", "--collision-usd", "--force"},
    "build-scene": {"--out", "--force"},
    "gen-trajectories": {"--scene", "--llm-api-key-env", "--force"},
    "render": {"--scene", "--pose", "--out", "--depth-out", "--instance-out", "--force"},
    "export-usd": {"--scene", "--cache-dir", "--force"},
    "validate": {"--scene", "--force"},
    "export-vlnce": {"--out", "--split"},
    "export-habitat": {"--out", "--split"},
    "export-training": {"--out"},
    "export-sage": {"--out", "--scene"},
    "import-sage-episodes": {"--run", "--scene", "--force"},
    "run": {"--force"},
    "verify": {"--regenerate", "--config", "--workers"},
    "evaluate": {"--run", "--predictions", "--out", "--scene", "--split", "--visualize", "--force"},
    "report": {"--out", "--predictions", "--scene"},
    "baseline": {"--run", "--out", "--scene", "--force"},
    "rollout": {"--run", "--out", "--scene", "--resume", "--force"},
}
OVERRIDES = {"run"}  # its options replace the run config's values


def _settings(command: str) -> dict[str, Setting]:
    module, name = SETTINGS[command]
    return {s.name: s for s in settings_of(getattr(importlib.import_module(module), name))}


def _model(command: str) -> type[BaseModel]:
    module, name = SETTINGS[command]
    return getattr(importlib.import_module(module), name)


def _shown(value: object) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def _expected_help(command: str, setting: Setting) -> str:
    """The field's description, and its default the way --help shows it."""
    text, value = setting.description, setting.default
    if command in OVERRIDES:
        return f"{text.removesuffix('.')} (default: the config's{'' if value is None else ', else ' + _shown(value)})."
    if setting.option.required:
        return f"{text}  [required]"
    if value in (None, ()) or isinstance(value, bool):
        return text
    return f"{text.removesuffix('.')} (default {_shown(value)})."


def _help(run_cli, command: str) -> dict[str, str]:
    """--help of COMMAND as option -> its help text, each on one line (click's help at a very wide terminal)."""
    import typer.main

    from sagebench.cli import app

    code, out, _ = run_cli(command, "--help")
    assert code == 0 and f"sagebench {command}" in out
    group = typer.main.get_command(app)
    root = typer.Context(group, info_name="sagebench", terminal_width=10_000, max_content_width=10_000)
    text = group.commands[command].get_help(typer.Context(group.commands[command], info_name=command, parent=root))
    return dict(re.findall(r"^  (--[a-z-]+)(?:, -\w)?(?: <[\w\[\]|]+>)?\s{2,}(.*?)\s*$", text, re.MULTILINE))


def _commands() -> list[str]:
    import typer.main

    from sagebench.cli import app

    return list(typer.main.get_command(app).commands)


def test_every_command_is_listed():
    assert set(_commands()) == set(NOT_SETTINGS) and set(SETTINGS) <= set(NOT_SETTINGS)


@pytest.mark.parametrize("command", list(NOT_SETTINGS))
def test_every_option_is_a_setting_whose_help_is_its_description(command, run_cli):
    """An option that is no field's (one typed into the command) fails, as does help that differs from the
    field's description or misstates its default."""
    settings = _settings(command) if command in SETTINGS else {}
    assert not settings.keys() & NOT_SETTINGS[command], "a field's option is listed as no setting"
    shown = {option: text for option, text in _help(run_cli, command).items() if option != "--help"}
    assert set(settings) <= set(shown), "a field declares an option the command does not have"
    for option, text in shown.items():
        if option in NOT_SETTINGS[command]:
            continue
        assert option in settings, f"{command} {option} is no settings field's option"
        assert text == _expected_help(command, settings[option]), option


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
            if m and m.group(1) in SETTINGS:
                found.setdefault(m.group(1), []).extend(re.findall(r"\[(--[a-z-]+)(?: ([^\]\s]+))?\]", usage))
    return found


def test_doc_option_blocks_match_help(run_cli):
    blocks = _doc_blocks()
    assert {"build-scene", "gen-trajectories", "export-usd", "validate"} <= set(blocks)
    for command, pairs in blocks.items():
        settings = _settings(command)
        shown = _help(run_cli, command)
        for option, value in pairs:
            assert option in shown, f"docs: {command} has no {option}"
            if option in settings and re.fullmatch(r"-?[0-9.]+", value) and command not in OVERRIDES:
                # a number is the default (an example for the run config's overrides); N, ID are placeholders
                default = settings[option].default
                assert float(value) == default, f"docs: {command} {option} {value}, but its default is {default}"


@pytest.mark.parametrize("command", sorted(set(SETTINGS) - OVERRIDES))  # run's are checked with its config
def test_a_bad_value_names_the_option(command):
    model, checked = _model(command), 0
    for option, setting in _settings(command).items():
        free = isinstance(setting.default, str | type(None)) and get_origin(setting.kind) is not Literal
        if free or setting.option.parse is not None:
            continue  # a free string (a URL, a model name) has no bad value of this kind; parsed text has its own
        with pytest.raises(ConfigError) as err:
            from_options(model, {option: "not a value"})
        assert str(err.value).startswith(f"{option}: "), str(err.value)
        checked += 1
    assert checked
