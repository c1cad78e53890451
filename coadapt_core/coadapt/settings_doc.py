"""docs/settings.md, generated from the settings tree of `coadapt run` (`CoadaptConfig`).

    python -m coadapt_core.coadapt.settings_doc > docs/settings.md

tests/core/test_settings.py regenerates the page and compares it with the committed one, and
compares its options with those of `coadapt run --help-all`."""

from __future__ import annotations

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
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    print(settings_markdown(), end="")
