"""Every command's options from settings classes: one declaration per setting.

A command declares what it takes as settings classes (`coadapt_core.settings`: `@settings`
and `setting(...)`, or `shared(...)` for a setting another command declares). `options_of`
makes each field an option (or, with `argument=`, a positional argument): its type and
names read from the declaration, its help and shown default rendered by the one help
renderer (`coadapt_core.cli.help`). `register` makes the command of those options and
records them in `DECLARED`, from which docs/settings.md is generated
(`coadapt_core.cli.settings_doc`) and against which the settings test compares every
command's --help. No command writes a `typer.Option` by hand (a test checks the sources).

What a command receives: each option's value as given on the command line, None when left
out; `settings_from` turns them into the settings object and `filled` into a plain mapping
(the declared defaults filled in, every value checked: a bad one is a `UserError`, one line
naming the setting and what it accepts, exit 2). `coadapt run` reads its config settings as
overrides instead (preset < YAML < option,
`coadapt_core.coadapt.config_loading.make_config`), so those options show the preset's
default.
"""

from __future__ import annotations

import inspect
import typing
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import typer

from coadapt_core.cli.help import option_help
from coadapt_core.settings_leaf import Leaf

#: command path ("run", "robot show", "" for `coadapt` itself) -> the option groups (one per
#: settings class) of its options, in the order --help lists them
DECLARED: dict[str, tuple[OptionGroup, ...]] = {}

#: the command-line type of each kind of setting (text is parsed by the setting's type)
_CLI_TYPES = {"bool": bool, "int": int, "float": float}


@dataclass(frozen=True)
class CommandOption:
    """One setting as a command-line parameter: its Python name, type, typer parameter and
    the setting it comes from."""

    param: str
    kind: Any
    option: Any
    leaf: Leaf
    names: tuple[str, ...]  # as declared, aliases included; () for a positional argument


def option_names(leaf: Leaf, aliases: tuple[str, ...] = ()) -> tuple[str, ...]:
    """The option's names as declared: `names`, else `--key` (`--key/--no-key` for a
    switch), then the declared `aliases` and `aliases`; () for a positional argument."""
    if leaf.extra.get("argument"):
        return ()
    names = tuple(leaf.extra.get("names") or ())
    if not names:
        names = (
            (f"{leaf.option}/--no-{leaf.option[2:]}",) if leaf.kind == "bool" else (leaf.option,)
        )
    return (*names, *tuple(leaf.extra.get("aliases") or ()), *aliases)


def _kind(leaf: Leaf) -> Any:
    """The type typer parses the option's text as (the setting's own checks come after)."""
    if leaf.annotation is Path:
        return Path
    if typing.get_origin(leaf.annotation) is list:
        return list[str]
    return _CLI_TYPES.get(leaf.kind, str)


class OptionGroup(list):
    """The `CommandOption`s of one settings class (`root`)."""

    def __init__(self, root: type, options: list[CommandOption]):
        super().__init__(options)
        self.root = root


class LateGroup(OptionGroup):
    """An option group made on first use (`make()`: an `OptionGroup`), for options read from
    the installed plugins (`coadapt run`'s aliases): the CLI starts without loading a plugin,
    and only a command that takes them, or asks for its help, makes them."""

    def __init__(
        self,
        make: Callable[[], OptionGroup],
        needed: Callable[[list[str]], bool] | None = None,
    ):
        list.__init__(self)
        self._make: Callable[[], OptionGroup] | None = make
        self._root: type | None = None
        #: whether a command line (the words after `coadapt`) needs these options (None: yes)
        self.needed = needed

    def _made(self) -> OptionGroup:
        if self._make is not None:
            group, self._make = self._make(), None
            list.extend(self, group)
            self._root = group.root
        return self

    def __iter__(self):
        return list.__iter__(self._made())

    def __len__(self) -> int:
        return list.__len__(self._made())

    def __getitem__(self, index: Any) -> Any:
        return list.__getitem__(self._made(), index)

    @property
    def root(self) -> type:
        return self._made()._root


class LateSignature:
    """`func` for typer, its signature the options of `groups` read when typer makes the
    command; a `LateGroup` among them only when `wanted(group)` (else its options are left
    out: the command is not the one being run, or its command line needs none of them)."""

    def __init__(
        self, func: Callable[..., Any], groups: tuple, wanted: Callable[[LateGroup], bool]
    ):
        self.func, self.groups, self.wanted = func, groups, wanted
        self.__name__ = self.__qualname__ = func.__name__
        self.__doc__, self.__module__ = func.__doc__, func.__module__

    def _groups(self) -> tuple:
        return tuple(g for g in self.groups if not isinstance(g, LateGroup) or self.wanted(g))

    @property
    def __signature__(self) -> inspect.Signature:
        return bind(lambda **_: None, *self._groups()).__signature__

    @property
    def __annotations__(self) -> dict[str, Any]:
        return {o.param: o.kind for group in self._groups() for o in group}

    def __call__(self, **values: Any) -> Any:
        return self.func(**values)


def options_of(
    cls: type,
    *,
    aliases: Mapping[str, tuple[str, ...]] | None = None,
    per_preset: bool = False,
    presets: dict[str, Any] | None = None,
) -> OptionGroup:
    """One `CommandOption` per command-line setting of the settings tree `cls` (nested
    sections expanded: `--task-commands-yaw-range`), its help rendered by
    `coadapt_core.cli.help.option_help`. `aliases` adds option names by key; `per_preset`:
    the settings of `coadapt run`'s config, whose shown default is the preset's (`presets`:
    `preset_defaults()` when already read; {} for settings no preset sets, which then show
    the default a preset would, none, without reading the config)."""
    from coadapt_core.settings import leaves

    if per_preset and presets is None:
        from coadapt_core.coadapt.config import preset_defaults

        presets = preset_defaults()
    out = []
    for leaf in leaves(cls):
        if not leaf.extra.get("cli", True):
            continue
        names = option_names(leaf, tuple((aliases or {}).get(leaf.key, ())))
        parameter = typer_parameter(
            ... if leaf.required else None,
            names,
            option_help(leaf, presets),
            metavar=leaf.extra.get("argument"),
            hidden=bool(leaf.extra.get("hidden")),
            callback=leaf.extra.get("callback"),
        )
        out.append(CommandOption(leaf.param, _kind(leaf), parameter, leaf, names))
    return OptionGroup(cls, out)


def typer_parameter(
    default: Any,
    names: tuple[str, ...],
    text: str,
    *,
    metavar: str | None = None,
    hidden: bool = False,
    callback: Callable[..., Any] | None = None,
) -> Any:
    """The typer parameter of one setting: an option of `names`, or the positional argument
    `metavar`; its help `text` (`coadapt_core.cli.help.option_help`)."""
    if metavar:
        return typer.Argument(default, metavar=metavar, help=text, show_default=False)
    return typer.Option(
        default, *names, help=text, hidden=hidden, callback=callback, is_eager=callback is not None
    )


@dataclass(frozen=True)
class EarlySwitch:
    """A switch of `coadapt` itself made without its settings class, so that `coadapt --help`
    imports no pydantic (a settings class costs pydantic's import, about twice `import typer`);
    its declaration is still the settings class's (`coadapt_core.cli.common_options.RootOptions`,
    from which docs/settings.md is generated), and tests/core/test_settings.py compares the two
    (names and help, word for word)."""

    param: str
    name: str
    help: str
    callback: Callable[[bool], None]

    @property
    def kind(self) -> Any:
        return bool

    @property
    def option(self) -> Any:
        return typer.Option(None, self.name, help=self.help, callback=self.callback, is_eager=True)


def bind(func: Callable[..., Any], *groups: list[CommandOption]) -> Callable[..., Any]:
    """`func(**values)` with a signature typer reads: the options of `groups`, in order."""
    params = [
        inspect.Parameter(
            o.param, inspect.Parameter.KEYWORD_ONLY, default=o.option, annotation=o.kind
        )
        for group in groups
        for o in group
    ]
    func.__signature__ = inspect.Signature(params)
    func.__annotations__ = {p.name: p.annotation for p in params}
    return func


def register(
    app: typer.Typer,
    name: str,
    func: Callable[..., Any],
    *groups: OptionGroup,
    path: str | None = None,
) -> None:
    """`func` as command `name` of `app`, its options those of `groups` (`options_of`),
    recorded in `DECLARED` under `path`, its full name ("robot show"; default `name`). A
    `LateGroup` among `groups` is made only when the command line runs this command (or
    names none, as the tests and the settings docs do)."""
    full = name if path is None else path
    if any(isinstance(g, LateGroup) for g in groups):
        app.command(name)(LateSignature(func, groups, lambda group: _runs(full, group)))
    else:
        app.command(name)(bind(func, *groups))
    DECLARED[full] = groups


def _runs(path: str, group: LateGroup) -> bool:
    """Whether the command line being run names command `path` and needs `group`'s options
    (or names no command yet: the tests, the settings docs)."""
    from coadapt_core.cli.common import invocation

    argv = invocation()
    if not argv:
        return True
    words = [w for w in argv if not w.startswith("-")]
    named = words[: len(path.split())] == path.split()
    return named and (group.needed is None or group.needed(argv))


def given_settings(values: Mapping[str, Any], options: list[CommandOption]) -> dict[str, Any]:
    """The settings given on the command line (not None), as a nested mapping of their keys."""
    out: dict[str, Any] = {}
    for option in options:
        if values.get(option.param) is not None:
            tree = out
            for part in option.leaf.path[:-1]:
                tree = tree.setdefault(part, {})
            tree[option.leaf.path[-1]] = values[option.param]
    return out


def settings_from(cls: type, values: Mapping[str, Any], options: list[CommandOption]) -> Any:
    """The settings object of `cls` from the options' values: those given over the declared
    defaults, checked; a bad value is a `UserError` naming the setting (one line, exit 2:
    `coadapt_core.cli.common.run_app`)."""
    return cls(**given_settings(values, options))


def filled(values: Mapping[str, Any], group: OptionGroup) -> dict[str, Any]:
    """`values` with the options of `group` replaced by its settings object's fields (the
    declared defaults of those left out; every value checked, `settings_from`)."""
    import dataclasses

    checked = settings_from(group.root, values, group)
    return {**values, **{f.name: getattr(checked, f.name) for f in dataclasses.fields(checked)}}


__all__ = [
    "DECLARED",
    "CommandOption",
    "EarlySwitch",
    "LateGroup",
    "OptionGroup",
    "bind",
    "filled",
    "given_settings",
    "option_names",
    "options_of",
    "register",
    "settings_from",
]
