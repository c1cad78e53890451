"""Typed settings: each setting is defined once, as a field of a settings dataclass.

A settings class is a pydantic dataclass made with `@settings`; each field is declared with
`setting(default, help, **constraints)`. From that one definition coadapt derives

- the YAML keys of a config file (nested sections are nested mappings),
- the command-line options of `coadapt run` and of the other commands with a settings
  class (`leaves` walks the tree; a nested key `task.commands.yaw_range` becomes
  `--task-commands-yaw-range`); a setting two commands share is declared in one of them
  and taken as it is by the other (`shared`),
- the checks: a bad value is a one-line `UserError` naming the key and what is accepted
  (`user_error` turns pydantic's report into that line),
- the table of settings in docs/settings.md (written by the command line's settings_doc.py
  with the same help renderer as --help, cli/help.py).

Command-line and YAML text is read by the field's type: a range `(low, high)` is written
`low:high` (or a YAML list), a mapping of numbers `name=value,name=value` (or a YAML mapping),
a tuple of integers `512,256,128` (or a YAML list).
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
from collections.abc import Iterator, Mapping
from typing import Annotated, Any

from pydantic import AfterValidator, BeforeValidator, ConfigDict, Field, ValidationError
from pydantic.dataclasses import dataclass as _pydantic_dataclass

from coadapt_core.errors import UserError, did_you_mean
from coadapt_core.io import jsonable
from coadapt_core.settings_leaf import Leaf, strip_optional

#: every settings class: unknown keys refused, no inf/nan
SETTINGS_CONFIG = ConfigDict(extra="forbid", allow_inf_nan=False)


def _not_bool(value: Any) -> Any:
    if isinstance(value, bool):
        raise ValueError("a number, not true/false")
    return value


def _split_text(value: Any) -> Any:
    """'0.5:1.5' -> ['0.5', '1.5']; '512,256' -> ['512', '256']; other values unchanged."""
    if isinstance(value, str):
        separator = ":" if ":" in value else ","
        return [p.strip() for p in value.split(separator) if p.strip()]
    return value


def _pairs_text(value: Any) -> Any:
    """'a=1,b=2' -> {'a': '1', 'b': '2'} (repeated command-line options arrive as a list)."""
    if isinstance(value, list | tuple) and all(isinstance(v, str) for v in value):
        value = ",".join(value)
    if isinstance(value, str):
        out = {}
        for part in [p.strip() for p in value.split(",") if p.strip()]:
            key, sep, number = part.partition("=")
            if not sep or not key.strip():
                raise ValueError(f"'{part}' is not name=value")
            out[key.strip()] = number.strip()
        return out
    return value


def _ordered(value: tuple[float, float]) -> tuple[float, float]:
    if value[0] > value[1]:
        raise ValueError("inverted: low must not exceed high")
    return value


def _positive(value: tuple[float, float]) -> tuple[float, float]:
    if value[0] <= 0:
        raise ValueError("both ends must be > 0")
    return value


def _nonnegative(value: tuple[float, float]) -> tuple[float, float]:
    if value[0] < 0:
        raise ValueError("both ends must be >= 0")
    return value


#: an integer (true/false refused; YAML and command-line text '24_000_000' accepted)
Int = Annotated[int, BeforeValidator(_not_bool)]
#: a finite number (true/false refused)
Float = Annotated[float, BeforeValidator(_not_bool)]
#: a range (low, high): 'low:high' on the command line, a two-item list in YAML
Range = Annotated[tuple[float, float], BeforeValidator(_split_text), AfterValidator(_ordered)]
#: a range of positive numbers
PositiveRange = Annotated[Range, AfterValidator(_positive)]
#: a range of numbers >= 0
NonNegativeRange = Annotated[Range, AfterValidator(_nonnegative)]
#: integers, 'a,b,c' on the command line
Ints = Annotated[tuple[int, ...], BeforeValidator(_split_text)]
#: name -> number, 'a=1,b=2' on the command line
Weights = Annotated[dict[str, float], BeforeValidator(_pairs_text)]


def setting(
    default: Any = dataclasses.MISSING,
    help: str = "",
    *,
    default_factory: Any = None,
    accepted: str | None = None,
    plugin: str | None = None,
    cli: bool = True,
    names: tuple[str, ...] = (),
    aliases: tuple[str, ...] = (),
    argument: str | None = None,
    hidden: bool = False,
    callback: Any = None,
    **constraints: Any,
) -> Any:
    """One setting: its default (none given: required), one line of help and its
    constraints (`ge`, `gt`, `le`, `lt`). `accepted` replaces the generated "what is
    accepted" text; `plugin` names the plugin kind whose installed names the help lists (a
    plugin setting whose default is None means the installed one of highest
    default_rank); `cli=False` keeps it off the command line (YAML only).

    Its command-line form (made by cli/options.py): the option is `--key` (`--key/--no-key`
    for a switch) unless `names` gives its names (`("-o", "--out")`, a switch without
    `--no-`); `aliases` adds older names; `argument` (a metavar) makes it a positional
    argument; `hidden` keeps it out of --help; `callback` runs as soon as the option is read
    (`--version`, `--help-all`)."""
    extra = {
        "accepted": accepted,
        "plugin": plugin,
        "cli": cli,
        "names": tuple(names),
        "aliases": tuple(aliases),
        "argument": argument,
        "hidden": hidden,
        "callback": callback,
    }
    kwargs: dict[str, Any] = dict(description=help, json_schema_extra=extra, **constraints)
    if default_factory is not None:
        return Field(default_factory=default_factory, **kwargs)
    return Field(... if default is dataclasses.MISSING else default, **kwargs)


@dataclasses.dataclass(frozen=True)
class _Shared:
    source: type
    name: str | None
    default: Any


def shared(source: type, name: str | None = None, *, default: Any = dataclasses.MISSING) -> Any:
    """A setting declared once, in settings class `source`, that another command's settings
    class takes as it is: type, help, constraints and (unless `default` is given) default.
    `name` is the field's name in `source` when it differs. The annotation written beside
    it is ignored (`Any` reads best): `terrain: Any = shared(CoadaptConfig)`."""
    return _Shared(source, name, default)


def _take_shared(cls: type) -> None:
    """Replace the `shared(...)` fields of class `cls` with their declarations."""
    import inspect

    annotations = dict(inspect.get_annotations(cls))
    for name, value in list(vars(cls).items()):
        if not isinstance(value, _Shared):
            continue
        info = value.source.__pydantic_fields__[value.name or name]
        annotations[name] = (
            Annotated[(info.annotation, *info.metadata)] if info.metadata else info.annotation
        )
        extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}
        kwargs: dict[str, Any] = dict(
            description=info.description, json_schema_extra={**extra, "shared": value.source}
        )
        if value.default is not dataclasses.MISSING:
            setattr(cls, name, Field(value.default, **kwargs))
        elif info.default_factory is not None:
            setattr(cls, name, Field(default_factory=info.default_factory, **kwargs))
        else:
            setattr(cls, name, Field(info.default, **kwargs))
    cls.__annotations__ = annotations


@contextlib.contextmanager
def _without_pydantic_plugins() -> Iterator[None]:
    """Within: pydantic loads no plugins of its own (`PYDANTIC_DISABLE_PLUGINS`), as typer does
    for the values it converts. A settings class checks a command line or a YAML file; looking
    for pydantic plugins (every installed package's entry points, read once per process) cost
    a command 0.05-0.09 s at a load of 11 on 2 cores, for plugins nothing here uses."""
    previous = os.environ.get("PYDANTIC_DISABLE_PLUGINS")
    os.environ["PYDANTIC_DISABLE_PLUGINS"] = "1"
    try:
        yield
    finally:
        if previous is None:
            del os.environ["PYDANTIC_DISABLE_PLUGINS"]
        else:
            os.environ["PYDANTIC_DISABLE_PLUGINS"] = previous


def settings(cls: type | None = None, *, prefix: str = "") -> Any:
    """Class decorator: `cls` as a pydantic dataclass whose construction turns a bad value
    into a one-line `UserError` (an error a `__post_init__` raises is passed on as is).
    `prefix` names the section in messages when the class is built on its own
    (`@settings(prefix="train")`: "train.epochs must be ..."). Fields given as `shared(...)`
    take another class's declaration."""
    if cls is None:
        return lambda c: settings(c, prefix=prefix)
    _take_shared(cls)
    with _without_pydantic_plugins():
        cls = _pydantic_dataclass(cls, config=SETTINGS_CONFIG)
    init = cls.__init__

    def __init__(self: Any, *args: Any, **kwargs: Any) -> None:
        try:
            init(self, *args, **kwargs)
        except ValidationError as exc:
            raise user_error(exc, type(self), prefix) from None

    __init__.__doc__ = init.__doc__
    cls.__init__ = __init__
    cls.__coadapt_settings__ = True
    return cls


def is_settings(cls: Any) -> bool:
    return isinstance(cls, type) and getattr(cls, "__coadapt_settings__", False)


# -- walking the tree ----------------------------------------------------------------------
def leaves(cls: type, prefix: tuple[str, ...] = ()) -> list[Leaf]:
    """Every setting of the tree rooted at settings class `cls`, nested sections expanded,
    in declaration order."""
    out: list[Leaf] = []
    for name, info in cls.__pydantic_fields__.items():
        inner = strip_optional(info.annotation)[0]
        if is_settings(inner):
            out.extend(leaves(inner, (*prefix, name)))
        else:
            out.append(Leaf((*prefix, name), info, cls))
    return out


def sections(cls: type) -> list[str]:
    """Names of the nested settings sections of `cls`."""
    return [
        n
        for n, i in cls.__pydantic_fields__.items()
        if is_settings(strip_optional(i.annotation)[0])
    ]


def to_plain(value: Any) -> Any:
    """A settings object (or anything inside one) as YAML/JSON data: tuples become lists
    (`coadapt_core.io.jsonable`, NaN kept)."""
    return jsonable(value, nan=math.nan)


# -- partial trees: overrides of a configuration that comes from elsewhere ------------------
def partial(
    cls: type,
    name: str,
    *,
    unset: str,
    doc: str = "",
    extra: dict[str, tuple[Any, Any]] | None = None,
    exclude: tuple[str, ...] = (),
) -> type:
    """A settings class with the fields of `cls`, each unset (None) by default: the
    overrides of a configuration that comes from elsewhere (a checkpoint). Types, help and
    constraints are `cls`'s; `unset` says in the help what an unset field means; `extra`
    adds fields ({name: (annotation, setting(...))}); `exclude` leaves fields out."""
    specs: list[tuple[str, Any, Any]] = []
    for field_name, info in cls.__pydantic_fields__.items():
        if field_name in exclude:
            continue
        inner = strip_optional(info.annotation)[0]
        base = {**(info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {})}
        if is_settings(inner):
            sub = partial(inner, f"{name}_{field_name}", unset=unset, doc=info.description or "")
            specs.append(
                (field_name, sub, setting(default_factory=sub, help=info.description or ""))
            )
            continue
        default = info.default_factory() if info.default_factory is not None else info.default
        annotation = Annotated[(inner, *info.metadata)] if info.metadata else inner
        field = Field(
            None,
            description=info.description,
            json_schema_extra={**base, "unset": unset, "base_default": default},
        )
        specs.append((field_name, annotation | None, field))
    for field_name, (annotation, field) in (extra or {}).items():
        specs.append((field_name, annotation, field))
    made = dataclasses.make_dataclass(name, specs)
    made.__module__ = cls.__module__
    made = settings(made)
    made.__doc__ = doc or cls.__doc__
    made.__base_settings__ = cls
    return made


def overrides(value: Any) -> dict[str, Any]:
    """The fields of a partial tree that are set, as nested plain data (unset ones left out)."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(value):
        item = getattr(value, f.name)
        if is_settings(type(item)):
            sub = overrides(item)
            if sub:
                out[f.name] = sub
        elif item is not None:
            out[f.name] = to_plain(item)
    return out


def apply_overrides(base: Any, changes: Mapping[str, Any]) -> Any:
    """A copy of settings object `base` with the nested `changes` applied, checked."""

    def merge(data: dict[str, Any], new: Mapping[str, Any]) -> dict[str, Any]:
        for key, value in new.items():
            nested = isinstance(value, Mapping) and isinstance(data.get(key), Mapping)
            data[key] = merge(dict(data[key]), value) if nested else value
        return data

    return type(base)(**merge(to_plain(base), changes))


# -- errors --------------------------------------------------------------------------------
def _find_leaf(cls: type, loc: tuple[Any, ...]) -> Leaf | None:
    names = tuple(str(p) for p in loc if not isinstance(p, int))
    best = None
    for leaf in leaves(cls):
        if names[: len(leaf.path)] == leaf.path and (
            best is None or len(leaf.path) > len(best.path)
        ):
            best = leaf
    return best


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def user_error(exc: ValidationError, cls: type, prefix: str = "") -> UserError:
    """pydantic's report of a bad value as one line naming the key and what is accepted."""
    err = exc.errors()[0]
    cause = (err.get("ctx") or {}).get("error")
    if isinstance(cause, UserError):
        return cause
    loc = tuple(err.get("loc") or ())
    if loc and loc[0] == 0 and len(loc) == 1:  # a positional argument
        loc = ()
    leaf = _find_leaf(cls, loc) if loc else None
    names = [str(p) for p in loc if not isinstance(p, int)]
    key = ".".join(([prefix] if prefix else []) + (list(leaf.path) if leaf else names))
    value = err.get("input")
    if err.get("type") in ("unexpected_keyword_argument", "extra_forbidden"):
        known = ", ".join(n for n in cls.__pydantic_fields__) if not leaf else ""
        parent = cls
        for name in names[:-1]:
            field = parent.__pydantic_fields__.get(name)
            parent = strip_optional(field.annotation)[0] if field else parent
        known = ", ".join(parent.__pydantic_fields__) if is_settings(parent) else known
        return UserError(f"unknown key '{key}'; accepted keys: {known}", field=key)
    if err.get("type") == "missing":
        return UserError(f"{key} is required", field=key)
    if leaf is None:
        return UserError(f"{key or cls.__name__}: {err.get('msg')}", field=key or None)
    if leaf.kind == "choice":
        choices = [str(c) for c in leaf.choices or ()]
        return UserError(
            f"{key} '{value}' is not one of {', '.join(choices)}{did_you_mean(value, choices)}",
            field=key,
        )
    detail = ""
    if err.get("type") == "value_error":
        detail = " (" + str(err.get("msg", "")).removeprefix("Value error, ") + ")"
    return UserError(f"{key} must be {leaf.accepted()}, got {_short(value)}{detail}", field=key)


__all__ = [
    "SETTINGS_CONFIG",
    "Float",
    "Int",
    "Ints",
    "NonNegativeRange",
    "PositiveRange",
    "Range",
    "Weights",
    "is_settings",
    "leaves",
    "sections",
    "setting",
    "settings",
    "shared",
    "to_plain",
    "user_error",
]
