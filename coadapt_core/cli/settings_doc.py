"""docs/settings.md, generated from the settings classes every command's options come from
(`coadapt_core.cli.options.DECLARED`): `coadapt run`'s config tree (`CoadaptConfig`, also its
YAML keys) first, then each command's own settings, command by command. Each setting's
meaning and default are those --help shows, from the same renderer (`coadapt_core.cli.help`).

    python -m coadapt_core.cli.settings_doc > docs/settings.md

tests/core/test_settings.py regenerates the page and compares it with the committed one, and
compares each command's options with those of its `--help` (`coadapt run --help-all`)."""

from __future__ import annotations

from typing import Any

from coadapt_core.cli.help import config_default, leaf_default, meaning
from coadapt_core.cli.options import DECLARED
from coadapt_core.coadapt.config import CoadaptConfig, preset_defaults
from coadapt_core.settings import leaves, sections

HEADER = """# Settings of every command

Generated from the one declaration of every setting: `coadapt run`'s config tree
(`CoadaptConfig` in `coadapt_core/coadapt/config.py`) and each command's settings classes,
named in its section, by `python -m coadapt_core.cli.settings_doc > docs/settings.md`.
Every option of every command comes from these declarations (`coadapt_core.cli.options`);
a test regenerates this page and compares each command's `--help` (`coadapt run --help-all`)
with it. A setting two commands share is declared once (`coadapt_core.settings.shared`)
and reads the same in both.

Each setting of `coadapt run`'s config is a YAML key of a `--config` file and of a run
folder's `config.yaml` (a dotted key is a nested mapping: `task.commands.yaw_range` is
`task: {commands: {yaw_range: [-1, 1]}}`) and a command-line option. Precedence: option >
YAML key > preset > default. No other command reads YAML. A bad value stops the command
with one line naming the key and what it accepts (exit 2).

Values on the command line: a range is `low:high`, integers `512,256,128`, weights
`name=value,name=value`; booleans `--x/--no-x` (YAML: true/false, yes/no, on/off).
"""

#: the column heads of a table of settings: with YAML keys (the run's config) or options only
_WITH_KEYS = ["| key | option | default | accepts | meaning |", "|---|---|---|---|---|"]
_OPTIONS_ONLY = ["| option | default | accepts | meaning |", "|---|---|---|---|"]


def _cell(text: str) -> str:
    return text.replace("|", "\\|")


def _names(option: Any) -> str:
    """The option's names as its row shows them, a switch without its `--no-` form (a
    positional argument: its metavar)."""
    if not option.names:
        return f"`{option.leaf.extra['argument']}` (argument)"
    return " ".join(f"`{name.split('/')[0]}`" for name in option.names)


def _config_rows(group: Any) -> list[list[str]]:
    """`coadapt run`'s config settings by section (the run's own first): heading and rows; a
    setting kept off the command line says "(YAML only)"."""
    nested, options = sections(CoadaptConfig), {option.leaf.key: option for option in group}
    presets = preset_defaults()
    groups: dict[str, list[str]] = {"run": []}
    for leaf in leaves(CoadaptConfig):
        section = leaf.path[0] if leaf.path[0] in nested else "run"
        empty = "{}" if leaf.kind == "mapping" else "''"
        default = _cell(config_default(leaf, presets) or empty)
        names = _names(options[leaf.key]) if leaf.key in options else "(YAML only)"
        groups.setdefault(section, []).append(
            f"| `{leaf.key}` | {names} | {default} | {leaf.accepted()} | {_cell(meaning(leaf))} |"
        )
    out = []
    for section, rows in groups.items():
        doc = (
            (CoadaptConfig.__pydantic_fields__[section].description or "").strip()
            if section != "run"
            else ""
        )
        out.append(
            [
                "\n## The run\n" if section == "run" else f"\n## `{section}`\n\n{doc}\n",
                *_WITH_KEYS,
                *rows,
            ]
        )
    return out


def _group_table(group: Any) -> list[str]:
    """One settings class of a command: its name, its docstring and one row per option."""
    cls = group.root
    doc = " ".join((cls.__doc__ or "").split())
    out = [f"`{cls.__module__}.{cls.__name__}`. {doc}\n", *_OPTIONS_ONLY]
    for option in group:
        leaf = option.leaf
        default = "required" if leaf.required else _cell(leaf_default(leaf) or "''")
        hidden = " (hidden from --help)" if leaf.extra.get("hidden") else ""
        out.append(
            f"| {_names(option)} | {default} | {leaf.accepted()} | {_cell(meaning(leaf))}{hidden} |"
        )
    return out


def command_order() -> list[str]:
    """Every command path with declared options: `run` first, then `robot`'s commands, then
    the others as `coadapt --help` lists them, `coadapt` itself last."""
    from coadapt_core.cli import COMMANDS

    # `robot`'s commands ("robot show", ...) in the order declared
    order = ["run", "robot", *(name for name in COMMANDS if name not in ("run", "robot"))]
    middle = sorted(
        (p for p in DECLARED if p not in ("run", "")),
        key=lambda p: order.index(p.split()[0]) if p.split()[0] in order else len(order),
    )
    return ["run", *middle] + ([""] if "" in DECLARED else [])


def settings_markdown() -> str:
    """The page: `coadapt run`'s config tree, one table per section, then every command's
    own settings."""
    from coadapt_core.cli import load_all

    load_all()  # making every command fills DECLARED

    out = [HEADER]
    for group in DECLARED["run"]:
        if group.root is CoadaptConfig:
            for table in _config_rows(group):
                out += table
    for path in command_order():
        groups = [g for g in DECLARED[path] if g.root is not CoadaptConfig]
        if not groups:
            continue
        title = f"`coadapt {path}`" if path else "`coadapt` itself"
        extra = " that are not config settings (no YAML key)" if path == "run" else ""
        out.append(f"\n# Options of {title}{extra}\n")
        for group in groups:
            out += [*_group_table(group), ""]
    return "\n".join(out).rstrip("\n") + "\n"


if __name__ == "__main__":
    print(settings_markdown(), end="")
