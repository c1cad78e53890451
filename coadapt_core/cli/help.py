"""The one renderer of help: what `--help` says of each option and what docs/settings.md
says of each setting, from the setting's declaration (`coadapt_core.settings`), in one pass.

A setting's help is its declared text (a default written into it by hand, "(default: X)",
taken out), what it accepts when that is a choice or a structured value, the installed
plugins when it names one, then its default, once, as `[default: X]` (`shown_default`).
`coadapt run`'s config settings show the preset's default instead (`config_default`: per
preset when the presets differ), since an option left out takes the preset's value.
`coadapt_core.cli.options` writes these texts into the options when a command is made;
`plain_help` then only sets the one layout of every command's --help (and `coadapt run
--help`'s short list); `coadapt_core.cli.settings_doc` writes the same defaults and
meanings into docs/settings.md.
"""

from __future__ import annotations

import re
import typing
from collections.abc import Callable
from typing import Any

import typer

from coadapt_core.settings_leaf import Leaf

#: "(default X)" / "(default: X)" written into a help text by hand
HAND_DEFAULT = re.compile(r"\s*(?:\(default:?\s+((?:[^()]|\([^()]*\))*)\)|\[default:\s*([^\]]*)\])")


def choices(kind: str) -> list[str]:
    """Registered names for a plugin kind (empty when the registry cannot be built)."""
    from coadapt_core.plugins import get_registry

    try:
        return get_registry().names(kind)
    except Exception:
        return []


def show_default(value: object) -> str:
    """A default as help shows it: on/off, 1_000_000, lists comma-separated."""
    if isinstance(value, bool):
        return "on" if value else "off"
    if isinstance(value, int) and abs(value) >= 10_000:
        return f"{value:_}"
    if isinstance(value, list | tuple):
        pair = len(value) == 2 and all(isinstance(v, float) for v in value)
        return (":" if pair else ",").join(map(str, value))
    if isinstance(value, dict):
        return ",".join(
            f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in value.items()
        )
    return str(value)


def meaning(leaf: Leaf) -> str:
    """The setting's declared help without a default written into it by hand."""
    return HAND_DEFAULT.sub("", leaf.help).strip()


def _hand_default(leaf: Leaf) -> str | None:
    found = HAND_DEFAULT.search(leaf.help)
    return (found.group(1) or found.group(2) or "").strip() if found else None


def leaf_default(leaf: Leaf) -> str | None:
    """A setting's default as help and docs/settings.md show it: a default its help writes
    "(default: ...)"; for a plugin, the rule and the plugin it picks now (`default_rank`);
    for an override, what unset means; else the declared value (None: nothing to show)."""
    hand = _hand_default(leaf)
    if hand is not None:
        return hand
    if leaf.extra.get("plugin"):  # declared by the plugins themselves (`default_rank`)
        many = typing.get_origin(leaf.annotation) is list
        return plugin_default(leaf.extra["plugin"], lambda: leaf.default, many)
    if leaf.extra.get("unset"):
        return f"{leaf.extra['unset']}, else {show_default(leaf.extra['base_default'])}"
    try:
        value = leaf.default
    except Exception:  # a default from the registry, which cannot be built: the command says why
        return None
    return None if value in ("", None) or value == {} else show_default(value)


def plugin_default(kind: str, default: Callable[[], Any], many: bool = False) -> str | None:
    """The shown default of a setting that names a plugin of `kind`: the rule and the plugin
    it picks now (`default()`, the setting's default value); `many`: a list, which names none
    when left unset."""
    rule = f"the installed {kind} of highest default_rank"
    try:
        value = default()
    except Exception:  # the registry cannot be built: the command reports why
        return rule
    if value is None:  # unset: the ranked one; a list left unset names none
        return None if many else rule
    return f"{value}, {rule}"


def config_default(leaf: Leaf, presets: dict[str, Any] | None = None) -> str | None:
    """The default of a `coadapt run` option that is a config setting (or a plugin option's
    alias): the value, or the value per preset when the presets differ; for a plugin or a
    learner setting, `leaf_default`'s. `presets`: `preset_defaults()`, when already read."""
    hand = _hand_default(leaf)
    if hand is not None:
        return hand
    if presets is None:
        from coadapt_core.coadapt.config import preset_defaults

        presets = preset_defaults()
    found = presets.get(leaf.param)
    if found is None:  # the preset itself, and names that are no config setting
        return leaf_default(leaf) if leaf.key == "preset" else None
    leaf, values = found
    if leaf.extra.get("plugin") or leaf.extra.get("unset"):
        return leaf_default(leaf)
    if all(v in ("", None) for v in values.values()):
        return None  # the help text says what an empty value means
    if len(set(map(repr, values.values()))) == 1:
        return show_default(next(iter(values.values())))
    return ", ".join(f"{show_default(v)} ({p})" for p, v in values.items())


def shown_default(leaf: Leaf, presets: dict[str, Any] | None = None) -> str | None:
    """The default --help shows at the end of the setting's help (None: none shown; a
    switch that is off shows none). `presets` (`preset_defaults()`): a config setting of
    `coadapt run`, whose default is the preset's (`config_default`)."""
    if presets is not None:
        return config_default(leaf, presets)
    if _hand_default(leaf) is None and leaf.kind == "bool" and leaf.default is False:
        return None
    return leaf_default(leaf)


#: help texts that name installed plugins, rendered when first read: the CLI starts, answers
#: `coadapt --help` and refuses a typo without loading a plugin (nor torch, which they import)
_DEFERRED: dict[str, Any] = {}
_DEFERRED_MARK = "\0coadapt-help:"


def _names_plugins(leaf: Leaf, presets: dict[str, Any] | None) -> bool:
    """Whether the setting's help may need the plugin registry: its choices, or its default
    (a plugin's, or one a function computes)."""
    found = (presets or {}).get(leaf.param)
    return any(
        x.extra.get("plugin") or x.info.default_factory is not None
        for x in (leaf, *(found[:1] if found else ()))
    )


def option_help(leaf: Leaf, presets: dict[str, Any] | None = None) -> str:
    """The help of a setting's option: its meaning, what it accepts when that is a choice
    or a structured value, the installed plugins when it names one, and its default once,
    as `[default: X]` (`shown_default`). A text naming plugins is a placeholder that
    `resolved` renders when the option's help is first read (`plain_help`)."""
    if not _names_plugins(leaf, presets):
        return _option_help(leaf, presets)
    return deferred(lambda: _option_help(leaf, presets))


def deferred(render: Callable[[], str]) -> str:
    """A placeholder help text that `resolved` renders (`render()`) when first read."""
    mark = f"{_DEFERRED_MARK}{len(_DEFERRED)}"
    _DEFERRED[mark] = render
    return mark


def plugin_help(meaning: str, kind: str, default: str | None) -> str:
    """The help of a setting naming a plugin of `kind`: its meaning, the installed plugins
    of that kind and its shown `default`."""
    names = choices(kind)
    text = f"{meaning} One of: {', '.join(names)}." if names else meaning
    return f"{text} [default: {default}]" if default else text


def resolved(text: Any) -> Any:
    """A help text with its placeholder rendered (`option_help`); any other value as it is."""
    if isinstance(text, str) and text.startswith(_DEFERRED_MARK):
        render = _DEFERRED[text]
        if callable(render):
            _DEFERRED[text] = render()
        return _DEFERRED[text]
    return text


_LAZY_CLASSES: dict[type, type] = {}


def _lazy_help(param: Any) -> None:
    """Make `param.help` render its placeholder when read (a subclass of its own class with
    `help` as a property), so Click, the tests and the docs read the full text."""
    base = type(param)
    if base not in _LAZY_CLASSES:
        _LAZY_CLASSES[base] = type(
            base.__name__,
            (base,),
            {
                "help": property(
                    lambda self: resolved(self.__dict__.get("help")),
                    lambda self, value: self.__dict__.__setitem__("help", value),
                )
            },
        )
    param.__class__ = _LAZY_CLASSES[base]


def _option_help(leaf: Leaf, presets: dict[str, Any] | None = None) -> str:
    text = meaning(leaf)
    if leaf.extra.get("plugin"):
        return plugin_help(text, leaf.extra["plugin"], shown_default(leaf, presets))
    if leaf.kind == "choice":
        text = f"{text} One of: {', '.join(map(str, leaf.choices or ()))}."
    elif leaf.kind in ("range", "ints", "weights"):
        text = f"{text} ({leaf.accepted()})"
    default = shown_default(leaf, presets)
    return f"{text} [default: {default}]" if default else text


#: what `coadapt run --help` shows, in this order; `--help-all` shows every option
RUN_COMMON_OPTIONS = (
    "config",
    "resume",
    "preset",
    "objective",
    "optimizer",
    "terrain",
    "method",
    "seed",
    "robot",
    "sim",
    "mixed",
    "checkpoint",
    "out",
    "store",
    "as_json",
    "quiet",
    "video",
    "device",
    "logger",
    "population",
    "outer_iterations",
    "optimizer_iterations",
    "train_steps",
    "eval_steps",
    "design_ranges",
)


def plain_help(command: Any) -> None:
    """One help layout for every command: plain Click help (no table: option names are never
    cut at 80 columns), each option's text as `option_help` wrote it (Click adds no default
    of its own); `coadapt run --help` lists the common options only (`short_help`, applied
    where the command is made: `coadapt_core.cli.make_command`)."""
    if hasattr(command, "rich_markup_mode"):
        command.rich_markup_mode = None
    for param in command.params:
        if getattr(param, "param_type_name", "") == "option":
            param.show_default = False
        if isinstance(param.__dict__.get("help"), str) and param.__dict__["help"].startswith(
            _DEFERRED_MARK
        ):
            _lazy_help(param)
    subs = getattr(command, "commands", {})
    # `coadapt` itself: only the commands made so far (`coadapt_core.cli.make_command` lays
    # out each one it makes, `coadapt run`'s short list included)
    for sub in getattr(subs, "made", subs).values():
        plain_help(sub)


def short_help(command: Any, common: tuple[str, ...]) -> None:
    """`--help` lists only the `common` options (in that order) and says how to see the
    rest; the command's `--help-all` option (`help_all`) lists every option, in its order."""
    original = command.format_options

    def format_options(ctx: Any, formatter: Any) -> None:
        if ctx.meta.get("coadapt_help_all"):
            return original(ctx, formatter)
        by_name = {p.name: p for p in command.get_params(ctx)}
        shown = [by_name[n] for n in common if n in by_name] + [
            by_name[n] for n in ("help_all", "help") if n in by_name
        ]
        records = [r for r in (p.get_help_record(ctx) for p in shown) if r]
        with formatter.section("Common options"):
            formatter.write_dl(records)
        hidden = sum(
            1
            for p in by_name.values()
            if getattr(p, "param_type_name", "") == "option" and not p.hidden and p not in shown
        )
        formatter.write_paragraph()
        formatter.write_text(
            f"{hidden} more options (training, task, randomization, surrogate, final check, "
            "optimizer aliases): `coadapt run --help-all`, or docs/settings.md."
        )

    command.format_options = format_options


def help_all(ctx: typer.Context, value: bool) -> None:
    """`--help-all`: the command's help with every option (see `short_help`)."""
    if not value or ctx.resilient_parsing:
        return
    ctx.meta["coadapt_help_all"] = True
    typer.echo(ctx.get_help())
    raise typer.Exit(0)
