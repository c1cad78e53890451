"""`coadapt train`'s and `coadapt eval`'s own options come from one declaration each
(`TrainCommand`, `EvalCommand` in coadapt_core/cli/train.py): the option, its --help and its
row in docs/settings.md; train's default objectives come from the installed plugins."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from coadapt_core.cli import train as train_cli
from coadapt_core.plugins import PluginInfo, Registry
from coadapt_core.settings import leaves

DOC = Path(__file__).resolve().parents[2] / "docs" / "settings.md"


def _command(name: str):
    from typer.main import get_command

    from coadapt_core.cli import app
    from coadapt_core.cli.common import style_help

    command = get_command(app)
    style_help(command)
    return command.commands[name]


def _documented(name: str) -> dict[str, tuple[str, str]]:
    """option -> (default, meaning) of the docs table of `coadapt <name>`."""
    section = DOC.read_text().split(f"\n# Settings of `coadapt {name}`\n")[1].split("\n# Settings of")[0]
    out = {}
    for row in section.splitlines():
        if row.startswith("| `--"):
            option, default, meaning = [c.strip() for c in re.split(r"(?<!\\)\|", row)[1:-1]]
            out[option.strip("`")] = (default, meaning.replace("\\|", "|"))
    return out


@pytest.mark.parametrize(("name", "cls"), [("train", train_cli.TrainCommand), ("eval", train_cli.EvalCommand)])
def test_docs_and_help_show_each_declared_option_its_help_and_default(name, cls):
    command = _command(name)
    helps = {opt: " ".join((p.help or "").split()) for p in command.params for opt in p.opts}
    documented = _documented(name)
    declared = {(leaf.extra.get("names") or (leaf.option,))[0].split("/")[0] for leaf in leaves(cls)}
    assert set(documented) == declared and declared <= set(helps)
    for option, (default, meaning) in documented.items():
        assert helps[option].startswith(meaning.rstrip(".")), option  # the declared help, word for word
        if default not in ("''", "off"):  # --help shows no default for a switch that is off
            assert helps[option].endswith(f"[default: {default}]"), option


def test_switches_keep_their_names():
    options = {opt for p in _command("train").params for opt in [*p.opts, *p.secondary_opts]}
    assert {"--mixed", "--no-mixed", "--quiet", "--reset-pseudo-critics", "--pseudo-critics-only"} <= options
    assert "--no-reset-pseudo-critics" not in options
    options = {opt for p in _command("eval").params for opt in [*p.opts, *p.secondary_opts]}
    assert {"--json", "--randomize", "--no-randomize", "--objective"} <= options and "--as-json" not in options


class _Objective:
    option_specs: tuple = ()

    def __init__(self, name: str, options: tuple = ()):
        self.name, self.option_specs = name, options


def test_default_objectives_are_the_installed_ones_without_options(monkeypatch):
    """Every installed objective that declares no options, in each plugin's own order: a
    third-party objective alone is trained by default; a configurable one (a weighted sum)
    only when named."""
    registry = Registry()
    for name, options, dist in (("zeta", (), "coadapt"), ("weighted", ("weights",), "coadapt"), ("alpha", (), "coadapt"),
                                ("theirs", (), "another-dist")):
        cls = type(name, (), {"name": name, "option_specs": options})
        registry.entries["objective"][name] = PluginInfo("objective", name, cls, dist, "0", "test")
    monkeypatch.setattr("coadapt_core.plugins.get_registry", lambda refresh=False: registry)
    assert train_cli.default_objectives() == ["theirs", "zeta", "alpha"]
