"""docs/settings.md, generated from the settings tree of `coadapt run` (`CoadaptConfig`) and
the settings classes of `coadapt train` and `coadapt eval` (`COMMAND_SETTINGS`).

    python -m coadapt_core.coadapt.settings_doc > docs/settings.md

tests/core/test_settings.py regenerates the page and compares it with the committed one, and
compares its options with those of `coadapt run --help-all`."""

from __future__ import annotations

import re
from typing import Any

HEADER = """# Settings of `coadapt run`

Generated from the one definition of every setting (`CoadaptConfig` in
`coadapt_core/coadapt/config.py`) by `python -m coadapt_core.coadapt.settings_doc >
docs/settings.md`; a test regenerates this page and compares it with `coadapt run --help-all`.
Each setting is a YAML key of a `--config` file and of a run folder's `config.yaml` (a
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


def settings_markdown() -> str:
    """The page: one table per section of the tree (the run's own settings first)."""
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
