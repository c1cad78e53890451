"""Options a plugin declares: typed, with a default and a help line.

An optimizer or objective plugin lists its options in the class attribute `option_specs`
(a tuple of `PluginOption`). coadapt then

- accepts them from YAML (`optimizer_options:` / `objective_options:` mappings) and from the
  command line (`--optimizer-option KEY=VALUE`, `--objective-option KEY=VALUE`, repeatable),
  CLI values winning key by key;
- converts and checks each value against its declaration (text from the command line is
  parsed as the declared type), so a bad value is one line naming the plugin, the option and
  what is accepted (exit 2), before any training is paid for;
- fills in the defaults, so the plugin reads every declared option from `self.options`;
- lists them in `coadapt plugins --json` (name, type, default, help, choices, bounds).

An option the plugin does not declare is refused, naming the ones it has.

An optimizer option may ask to be filled from the run (`from_run`, one of `RUN_FACTS`) when
the run leaves it unset: the co-adaptation loop then passes that fact of the run (a name
unique to the run and outer iteration, the results store's URL), whatever the plugin.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from coadapt_core.errors import UserError

#: the option an optimizer declares when it keeps a study in a database (a URL, e.g. an
#: optuna storage): the loop and `coadapt grid` fill it with the run's results store
STUDY_STORAGE_OPTION = "storage"
#: the types an option may declare
OPTION_TYPES: dict[str, type] = {"int": int, "float": float, "str": str, "bool": bool}
#: facts of a run the co-adaptation loop fills into an optimizer option declared with
#: `from_run` when the run leaves it unset (`fill_from_run`)
RUN_FACTS: dict[str, str] = {
    "run_name": "a name unique to the run and its outer iteration: <run id>-outer<k>",
    "store_url": "the URL of the run's results store, when it is a database URL (scheme://...)",
    "start_design": "the design a descent starts from, comma-separated: the robot's nominal "
    "design in the first outer iteration, the lowest real cost so far after it",
}
_TRUE = {"true", "yes", "on", "1"}
_FALSE = {"false", "no", "off", "0"}


@dataclass(frozen=True)
class PluginOption:
    """One declared option.

    type: "int", "float", "str" or "bool". `choices` (a tuple of accepted values) and
    `minimum` / `maximum` (inclusive bounds, numbers only) are checked; a default of None
    means "not set" (the plugin decides, e.g. an in-memory study when no storage is given).
    `from_run` (a key of `RUN_FACTS`): an optimizer option the co-adaptation loop fills with
    that fact of the run when the run leaves it unset. `alias` (optional) is a top-level config
    key and `coadapt run` option (`--<alias>`, underscores as dashes) that sets this option:
    kept for the keys of earlier versions."""

    name: str
    type: str
    default: Any
    help: str
    choices: tuple[Any, ...] | None = None
    minimum: float | None = None
    maximum: float | None = None
    from_run: str | None = None
    alias: str | None = None

    def __post_init__(self) -> None:
        if self.type not in OPTION_TYPES:
            raise TypeError(
                f"option '{self.name}' has type {self.type!r}; use one of {', '.join(OPTION_TYPES)}"
            )
        if self.from_run is not None and self.from_run not in RUN_FACTS:
            raise TypeError(
                f"option '{self.name}' is filled from_run={self.from_run!r}; "
                f"use one of {', '.join(RUN_FACTS)}"
            )

    def convert(self, value: Any, owner: str, field: str) -> Any:
        """`value` (a YAML value or command-line text) as the declared type, checked."""
        if value is None:
            return None
        what = f"{owner} option '{self.name}'"
        accepted = self.accepted()
        try:
            if self.type == "bool":
                if isinstance(value, bool):
                    out: Any = value
                elif isinstance(value, str) and value.strip().lower() in _TRUE | _FALSE:
                    out = value.strip().lower() in _TRUE
                else:
                    raise ValueError
            elif self.type == "int":
                if isinstance(value, bool) or (isinstance(value, float) and not value.is_integer()):
                    raise ValueError
                out = int(value.replace("_", "")) if isinstance(value, str) else int(value)
            elif self.type == "float":
                if isinstance(value, bool):
                    raise ValueError
                out = float(value)
                if not math.isfinite(out):
                    raise ValueError
            else:
                if isinstance(value, Mapping | list | tuple):
                    raise ValueError
                out = str(value)
        except (TypeError, ValueError):
            raise UserError(f"{what} must be {accepted}, got {value!r}", field=field) from None
        if self.choices is not None and out not in self.choices:
            raise UserError(f"{what} must be {accepted}, got {value!r}", field=field)
        if self.minimum is not None and out < self.minimum:
            raise UserError(f"{what} must be {accepted}, got {value!r}", field=field)
        if self.maximum is not None and out > self.maximum:
            raise UserError(f"{what} must be {accepted}, got {value!r}", field=field)
        return out

    def accepted(self) -> str:
        if self.choices is not None:
            return "one of " + ", ".join(str(c) for c in self.choices)
        kind = {
            "int": "an integer",
            "float": "a finite number",
            "str": "text",
            "bool": "true or false",
        }[self.type]
        if self.minimum is not None and self.maximum is not None:
            return f"{kind} in [{self.minimum:g}, {self.maximum:g}]"
        if self.minimum is not None:
            return f"{kind} >= {self.minimum:g}"
        if self.maximum is not None:
            return f"{kind} <= {self.maximum:g}"
        return kind

    def to_dict(self) -> dict[str, Any]:
        out = {
            "name": self.name,
            "type": self.type,
            "default": self.default,
            "help": self.help,
            "choices": None if self.choices is None else list(self.choices),
            "minimum": self.minimum,
            "maximum": self.maximum,
        }
        return out | ({"alias": self.alias} if self.alias else {})


def resolve_options(
    specs: Sequence[PluginOption], given: Mapping[str, Any] | None, *, owner: str, field: str
) -> dict[str, Any]:
    """`given` checked against `specs`, with every declared default filled in.

    `owner` names the plugin in messages ("optimizer 'pso'"); `field` is the config key the
    values came from ("optimizer_options")."""
    by_name = {spec.name: spec for spec in specs}
    out = {spec.name: spec.default for spec in specs}
    for key, value in (given or {}).items():
        key = str(key).replace("-", "_")
        spec = by_name.get(key)
        if spec is None:
            listing = ", ".join(by_name) or "none"
            raise UserError(f"{owner} has no option '{key}'; its options: {listing}", field=field)
        out[key] = spec.convert(value, owner, field)
    return out


def fill_from_run(
    specs: Sequence[PluginOption], given: Mapping[str, Any], facts: Mapping[str, Any]
) -> dict[str, Any]:
    """`given` with each option declared `from_run` that is unset (absent, None or empty)
    set to that fact of the run (`facts`, keys of `RUN_FACTS`); a fact the run does not have
    (None) leaves the option unset."""
    out = dict(given)
    for spec in specs:
        fact = facts.get(spec.from_run) if spec.from_run else None
        if fact is not None and not out.get(spec.name):
            out[spec.name] = fact
    return out


def parse_assignments(items: Sequence[str] | None, field: str) -> dict[str, str]:
    """['sigma=0.3', 'popsize=8'] (repeated `--optimizer-option`) -> {'sigma': '0.3', ...};
    values stay text until the plugin's declarations convert them."""
    out: dict[str, str] = {}
    for item in items or []:
        key, sep, value = str(item).partition("=")
        if not sep or not key.strip():
            raise UserError(
                f"--{field.replace('_', '-')[:-1]} '{item}' must look like KEY=VALUE", field=field
            )
        out[key.strip().replace("-", "_")] = value.strip()
    return out


def check_specs(specs: Any, owner: str) -> tuple[PluginOption, ...]:
    """The declared specs as a tuple, or a TypeError naming what is wrong (registry and
    conformance suites use it)."""
    if not isinstance(specs, tuple | list):
        raise TypeError(
            f"{owner}: option_specs must be a tuple of PluginOption, got {type(specs).__name__}"
        )
    names = set()
    for spec in specs:
        if not isinstance(spec, PluginOption):
            raise TypeError(f"{owner}: option_specs holds {spec!r}, not a PluginOption")
        if spec.name in names:
            raise TypeError(f"{owner}: option '{spec.name}' is declared twice")
        names.add(spec.name)
        if spec.alias is not None and not (
            isinstance(spec.alias, str) and spec.alias.isidentifier()
        ):
            raise TypeError(
                f"{owner}: option '{spec.name}' has alias {spec.alias!r}; "
                "use a name like 'my_option'"
            )
        if spec.default is not None:
            spec.convert(spec.default, owner, "option_specs")
    return tuple(specs)


__all__ = ["OPTION_TYPES", "PluginOption", "check_specs", "parse_assignments", "resolve_options"]
