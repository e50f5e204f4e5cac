"""A command's settings options, made from its settings model (sagebench/settings/) when the command is parsed or
its help shown, so a run of another command imports none of it.

Each field that declares an Option becomes one typer option: its description is the help, "(default X)" is
added from the field's default (the run command's options replace the config's: "(default: the config's, else
X)"), and an option the user does not give is left out, so the model's default applies. The command reads the
options given with `given(ctx)`, or its settings with `settings(ctx)`.
"""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Annotated, Any, Literal, get_origin

import typer
import typer.core
import typer.main

if TYPE_CHECKING:
    from pydantic import BaseModel

    from sagebench.settings.option import Setting

GIVEN = "sagebench.settings"  # ctx.meta key of the settings options given: {"--band-max": 1.8}


def settings_command(model: str, *, before: str = "--force", overrides: bool = False
                     ) -> type[typer.core.TyperCommand]:
    """The class of a command whose settings are `model` ("module:Model"): their options follow the command's own,
    up to the option `before` (or the end); with `overrides` they replace values a config file gives (their help
    says so)."""

    class Command(typer.core.TyperCommand):
        model: type[BaseModel]
        _settings: dict[str, Setting] | None = None  # the options' parameter names -> their settings
        _options: list = []

        def get_params(self, ctx: typer.Context) -> list:
            if self._settings is None:
                module, name = model.split(":")
                self.model = getattr(importlib.import_module(module), name)
                self._settings, self._options = setting_options(self.model, overrides=overrides)
            own = super().get_params(ctx)
            at = next(i for i, p in enumerate(own) if before in p.opts or p.name == "help")
            return [*own[:at], *self._options, *own[at:]]

        def invoke(self, ctx: typer.Context) -> Any:
            settings = self._settings or {}
            ctx.meta[GIVEN] = {settings[k].name: _value(settings[k], ctx.params.pop(k))
                               for k in list(ctx.params) if k in settings}
            return super().invoke(ctx)

    return Command


def given(ctx: typer.Context) -> Mapping[str, object]:
    """The settings options the user gave this command ({"--band-max": 1.8}); the model's defaults fill the rest."""
    return {option: value for option, value in ctx.meta.get(GIVEN, {}).items() if value not in (None, ())}


def settings(ctx: typer.Context) -> BaseModel:
    """The command's settings: its model from the options given; a bad value is one ConfigError naming the option."""
    from sagebench.settings.option import from_options

    return from_options(ctx.command.model, given(ctx))


def setting_options(model: type[BaseModel], *, overrides: bool = False) -> tuple[dict[str, Setting], list]:
    """(parameter name -> Setting, the typer options) of a settings model: typer makes them from a function
    signature, as it makes a command's own."""
    from sagebench.settings.option import settings_of

    settings = {"setting__" + s.path.replace(".", "__"): s for s in settings_of(model)}
    app = typer.Typer(add_completion=False)
    app.command()(_signed(inspect.Signature([_parameter(name, s, overrides) for name, s in settings.items()])))
    return settings, list(typer.main.get_command(app).params)


def _signed(signature: inspect.Signature) -> Callable[..., None]:
    def options(**_: object) -> None:
        """The settings options (never called)."""

    options.__signature__ = signature  # type: ignore[attr-defined]
    return options


def _parameter(name: str, setting: Setting, overrides: bool) -> inspect.Parameter:
    kind = setting.kind
    if setting.option.parse is not None or get_origin(kind) is Literal:
        kind = str
    elif get_origin(kind) is tuple:
        kind = list[str]
    option = typer.Option(setting.name, help=help_text(setting, overrides=overrides),
                          autocompletion=_completion(setting.choices) if setting.choices else None)
    if setting.option.required:
        return inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, annotation=Annotated[kind, option])
    return inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=None,
                             annotation=Annotated[kind | None, option])


def _value(setting: Setting, value: object) -> object:
    """What an option's value sets: a flag given sets the other value than the field's default (--no-views)."""
    if setting.kind is bool:
        return (not setting.default) if value else None
    return tuple(value) if isinstance(value, list) else value


def help_text(setting: Setting, *, overrides: bool = False) -> str:
    """The field's description, with its default where one helps: "(default 0.05)"; none for a flag, a required
    option or a default of nothing."""
    value = setting.default
    if overrides:
        shown = "" if value is None else f", else {_shown(value)}"
        return f"{setting.description.removesuffix('.')} (default: the config's{shown})."
    if value in (None, ()) or isinstance(value, bool) or setting.option.required:
        return setting.description
    return f"{setting.description.removesuffix('.')} (default {_shown(value)})."


def _shown(value: object) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def _completion(choices: tuple[str, ...]) -> Callable[[str], list[str]]:
    def complete(incomplete: str) -> list[str]:
        return [c for c in choices if c.startswith(incomplete)]

    return complete
