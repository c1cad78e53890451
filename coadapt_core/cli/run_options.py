"""`coadapt run`'s config options without its config: the option of every config setting
(names, type, help with the presets' defaults), stored in `run_options.json` beside this file,
so that `coadapt run --help` and the refusal of a bad option answer without loading pydantic's
models of the run's settings (`coadapt_core.coadapt.config`, about 0.3 s on a slow CPU). The
run itself still reads every value through `CoadaptConfig` (`make_config`).

The table is generated from the config's declaration, like docs/settings.md:

    python -m coadapt_core.cli.run_options > coadapt_core/cli/run_options.json

and tests/core/test_settings.py fails when it differs from what the config declares now. A help
text that names installed plugins (`--robot`, `--sim`, `--optimizer`, `--objective`) is stored
as its parts and rendered when first read, from the registry (`coadapt_core.cli.help`).
"""

from __future__ import annotations

import functools
import json
import typing
from pathlib import Path
from typing import Any

from coadapt_core.cli.help import deferred, plugin_default, plugin_help
from coadapt_core.cli.options import CommandOption, OptionGroup, typer_parameter

TABLE = Path(__file__).with_name("run_options.json")

#: the command-line type of each option, by the name the table gives it
_TYPES: dict[str, Any] = {"bool": bool, "int": int, "float": float, "str": str, "path": Path}


@functools.cache
def stored() -> dict[str, Any]:
    """The table: `settings` (the config's top-level names), `params` (every setting's
    parameter name, YAML-only ones included) and `options` (one row per option)."""
    return json.loads(TABLE.read_text(encoding="utf-8"))


class StoredLeaf:
    """A config setting as the table names it: its key, path, parameter and option, which
    is what making and running `coadapt run` read. Any other attribute is the setting's own
    (`coadapt_core.settings_leaf.Leaf`), read from `CoadaptConfig` when first asked for
    (docs/settings.md, the tests)."""

    def __init__(self, key: str):
        self.key = key
        self.path = tuple(key.split("."))
        self.param = "_".join(self.path)
        self.option = "--" + "-".join(self.path).replace("_", "-")

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(_leaves()[self.key], name)


@functools.cache
def _leaves() -> dict[str, Any]:
    from coadapt_core.coadapt.config import CoadaptConfig
    from coadapt_core.settings import leaves

    return {leaf.key: leaf for leaf in leaves(CoadaptConfig)}


class StoredGroup(OptionGroup):
    """The options of `coadapt run`'s config settings, made from the table; its `root` (the
    settings class, `CoadaptConfig`) is imported when read."""

    def __init__(self, options: list[CommandOption]):
        list.__init__(self, options)

    @property
    def root(self) -> type:
        from coadapt_core.coadapt.config import CoadaptConfig

        return CoadaptConfig


def _help(row: dict[str, Any]) -> str:
    """A row's help: as stored, or (a setting naming a plugin) rendered when first read."""
    if "help" in row:
        return row["help"]
    kind = row["plugin"]

    def render() -> str:
        from coadapt_core.plugins import default_plugin

        shown = row["hand"] or plugin_default(kind, lambda: default_plugin(kind), row["many"])
        return plugin_help(row["meaning"], kind, shown)

    return deferred(render)


def config_options() -> StoredGroup:
    """The option of every config setting on the command line, from the table."""
    out = []
    for row in stored()["options"]:
        names = tuple(row["names"])
        parameter = typer_parameter(None, names, _help(row), hidden=row["hidden"])
        kind = list[str] if row["type"] == "list" else _TYPES[row["type"]]
        leaf = StoredLeaf(row["key"])
        out.append(CommandOption(leaf.param, kind, parameter, leaf, names))
    return StoredGroup(out)


def build() -> dict[str, Any]:
    """The table from the config's declaration (`CoadaptConfig`, its presets, the renamed
    keys' options): what `run_options.json` holds."""
    from coadapt_core.cli.help import (
        _hand_default,
        _names_plugins,
        meaning,
        option_help,
        resolved,
    )
    from coadapt_core.cli.options import _kind, option_names
    from coadapt_core.coadapt.config import FIELD_NAMES, CoadaptConfig, preset_defaults
    from coadapt_core.coadapt.config_aliases import OPTION_ALIASES
    from coadapt_core.settings import leaves

    presets, types = preset_defaults(), {v: k for k, v in _TYPES.items()}
    rows = []
    for leaf in leaves(CoadaptConfig):
        if not leaf.extra.get("cli", True):
            continue
        if leaf.required or leaf.extra.get("callback") or leaf.extra.get("argument"):
            raise ValueError(f"{leaf.key}: the table holds optional options only")
        kind = _kind(leaf)
        row: dict[str, Any] = {
            "key": leaf.key,
            "names": list(option_names(leaf, OPTION_ALIASES.get(leaf.key, ()))),
            "type": "list" if kind == list[str] else types[kind],
            "hidden": bool(leaf.extra.get("hidden")),
        }
        if leaf.extra.get("plugin"):
            row["plugin"], row["meaning"] = leaf.extra["plugin"], meaning(leaf)
            row["hand"] = _hand_default(leaf)
            row["many"] = typing.get_origin(leaf.annotation) is list
        elif _names_plugins(leaf, presets) and leaf.info.default_factory not in (dict, list):
            raise ValueError(f"{leaf.key}: a default computed when shown cannot be stored")
        else:
            row["help"] = resolved(option_help(leaf, presets))
        rows.append(row)
    return {
        "settings": list(FIELD_NAMES),
        "params": [leaf.param for leaf in leaves(CoadaptConfig)],
        "options": rows,
    }


def table_text() -> str:
    """`build()` as `run_options.json` holds it."""
    return json.dumps(build(), indent=1, ensure_ascii=False) + "\n"


if __name__ == "__main__":
    print(table_text(), end="")
