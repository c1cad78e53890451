"""docs/settings.md, generated from the settings trees of the commands: `coadapt run`'s
(`CoadaptConfig`), then every other command's (`COMMANDS`: landscape, grid; `COMMAND_SETTINGS`:
train, eval).

    python -m coadapt_core.coadapt.settings_doc > docs/settings.md

tests/core/test_settings.py regenerates the page and compares it with the committed one, and
compares each command's options with those of its `--help` (`coadapt run --help-all`)."""

from __future__ import annotations

import importlib
import re
from typing import Any

#: command -> "module:settings class" of every command whose options come from a settings
#: tree, `coadapt run` first
COMMANDS: dict[str, str] = {
    "run": "coadapt_core.coadapt.config:CoadaptConfig",
    "landscape": "coadapt_core.cli.landscape:LandscapeSettings",
    "grid": "coadapt_core.cli.grid:GridSettings",
}

HEADER = """# Settings of `coadapt run` and the other commands

Generated from the one definition of every setting (`CoadaptConfig` in
`coadapt_core/coadapt/config.py`; each other command's settings class, named in its section)
by `python -m coadapt_core.coadapt.settings_doc > docs/settings.md`; a test regenerates this
page and compares it with each command's `--help` (`coadapt run --help-all`). A setting two
commands share is declared once (`coadapt_core.settings.shared`) and reads the same in both.
Each setting of `coadapt run` is a YAML key of a `--config` file and of a run folder's `config.yaml` (a
dotted key is a nested mapping: `task.commands.yaw_range` is `task: {commands: {yaw_range:
[-1, 1]}}`) and a command-line option. Precedence: option > YAML key > preset > default.
A bad value stops the command with one line naming the key and what it accepts (exit 2).

Values on the command line: a range is `low:high`, integers `512,256,128`, weights
`name=value,name=value`; booleans `--x/--no-x` (YAML: true/false, yes/no, on/off).
The settings of `coadapt train` and `coadapt eval` follow the run's, at the end of the page.
"""


def _default(leaf: Any) -> str:
    from coadapt_core.cli.common import config_default

    empty = "{}" if leaf.kind == "mapping" else "''"
    return (config_default(leaf.param) or empty).replace("|", "\\|")


def settings_class(command: str) -> type:
    """The settings class of `command` (`COMMANDS`)."""
    module, _, name = COMMANDS[command].partition(":")
    return getattr(importlib.import_module(module), name)


def _command_table(command: str) -> list[str]:
    """The section of a command without presets or YAML: one row per option."""
    from coadapt_core.cli.common import _HAND_DEFAULT, leaf_default
    from coadapt_core.settings import leaves

    cls = settings_class(command)
    doc = " ".join((cls.__doc__ or "").split())
    out = [f"\n## `coadapt {command}`\n", f"`{cls.__module__}.{cls.__name__}`. {doc}\n",
           "| key | option | default | accepts | meaning |", "|---|---|---|---|---|"]
    for leaf in leaves(cls):
        meaning = _HAND_DEFAULT.sub("", leaf.help).strip().replace("|", "\\|")
        default = (leaf_default(leaf) or "''").replace("|", "\\|")
        out.append(f"| `{leaf.key}` | `{leaf.option}` | {default} | {leaf.accepted()} | {meaning} |")
    return out


def settings_markdown() -> str:
    """The page: one table per section of the run's tree (its own settings first), then one
    per other command."""
    from coadapt_core.coadapt.config import CoadaptConfig
    from coadapt_core.settings import leaves, sections

    nested = sections(CoadaptConfig)
    groups: dict[str, list[Any]] = {"run": []}
    for leaf in leaves(CoadaptConfig):
        group = leaf.path[0] if leaf.path[0] in nested else "run"
        groups.setdefault(group, []).append(leaf)
    out = [HEADER]
    for group, items in groups.items():
        if group != "run":
            doc = (CoadaptConfig.__pydantic_fields__[group].description or "").strip()
            out.append(f"\n## `{group}`\n\n{doc}\n")
        else:
            out.append("\n## The run\n")
        out.append("| key | option | default | accepts | meaning |")
        out.append("|---|---|---|---|---|")
        for leaf in items:
            option = f"`{leaf.option}`" if leaf.extra.get("cli", True) else "(YAML only)"
            meaning = leaf.help.replace("|", "\\|")
            out.append(f"| `{leaf.key}` | {option} | {_default(leaf)} | {leaf.accepted()} | {meaning} |")
    for command in COMMANDS:
        if command != "run":
            out += _command_table(command)
    return "\n".join(out) + "\n" + command_markdown()


#: the commands whose own settings follow the run's on the page: (command, module, settings
#: class, what else the command takes)
COMMAND_SETTINGS = (
    ("train", "coadapt_core.cli.train", "TrainCommand",
     "Also every setting of the `train`, `task` and `randomization` sections above, as the same options, each an "
     "override of the checkpoint's (--resume / --init-from), else of the default."),
    ("eval", "coadapt_core.cli.train", "EvalCommand", ""),
)


def _command_default(leaf: Any) -> str:
    """A command setting's default as its --help shows it: the rule for a plugin left unset,
    the "(default: ...)" its help writes, else the declared value."""
    from coadapt_core.cli.common import show_default

    found = re.search(r"\(default: ((?:[^()]|\([^()]*\))*)\)", leaf.help)
    if found:
        return found.group(1)
    if leaf.extra.get("ranked"):
        return f"the installed {leaf.extra['plugin']} of highest default_rank"
    return "''" if leaf.default in (None, "") else show_default(leaf.default)


def command_markdown() -> str:
    """One section per command of `COMMAND_SETTINGS`: a table of its own settings (options only)."""
    from importlib import import_module

    from coadapt_core.settings import leaves

    out = []
    for command, module, name, note in COMMAND_SETTINGS:
        cls = getattr(import_module(module), name)
        out.append(f"\n# Settings of `coadapt {command}`\n\nDeclared once in `{name}` ({module.replace('.', '/')}.py): "
                   f"each is an option of `coadapt {command}` (no YAML file). {note}".rstrip() + "\n")
        out.append("| option | default | meaning |")
        out.append("|---|---|---|")
        for leaf in leaves(cls):
            names = " ".join(f"`{n.split('/')[0]}`" for n in leaf.extra.get("names") or ()) or f"`{leaf.option}`"
            meaning = re.sub(r"\s*\(default: ((?:[^()]|\([^()]*\))*)\)", "", leaf.help).replace("|", "\\|")
            out.append(f"| {names} | {_command_default(leaf)} | {meaning} |")
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    print(settings_markdown(), end="")
