"""`coadapt train`'s and `coadapt eval`'s own options come from one declaration each
(`TrainCommand` in coadapt_core/cli/train.py, `EvalCommand` in coadapt_core/cli/evaluate.py):
the option, its --help and its row in docs/settings.md; train's default objectives come from
the installed plugins."""

from __future__ import annotations

import pytest

from coadapt_core.cli import evaluate as eval_cli
from coadapt_core.cli import train as train_cli
from coadapt_core.cli import train_setup
from coadapt_core.cli.options import option_names
from coadapt_core.plugins import PluginInfo, Registry
from coadapt_core.settings import leaves
from tests.core.test_settings import _command
from tests.core.test_settings import documented as documented_rows


@pytest.mark.parametrize(
    ("name", "cls"), [("train", train_cli.TrainCommand), ("eval", eval_cli.EvalCommand)]
)
def test_docs_and_help_show_each_declared_option_its_help_and_default(name, cls):
    command = _command(name)
    helps = {opt: " ".join((p.help or "").split()) for p in command.params for opt in p.opts}
    documented = {
        option: row
        for option, row in documented_rows(name).items()
        if option.lstrip("-").replace("-", "_") in {leaf.param for leaf in leaves(cls)} | {"json"}
    }
    declared = {option_names(leaf)[0].split("/")[0] for leaf in leaves(cls)}
    assert set(documented) == declared and declared <= set(helps)
    for option, (meaning, default) in documented.items():
        assert helps[option].startswith(meaning.rstrip(".")), (
            option
        )  # the declared help, word for word
        if default not in ("''", "off"):  # --help shows no default for a switch that is off
            assert helps[option].endswith(f"[default: {default}]"), option


def test_switches_keep_their_names():
    options = {opt for p in _command("train").params for opt in [*p.opts, *p.secondary_opts]}
    assert {
        "--mixed",
        "--no-mixed",
        "--quiet",
        "--reset-pseudo-critics",
        "--pseudo-critics-only",
    } <= options
    assert "--no-reset-pseudo-critics" not in options
    options = {opt for p in _command("eval").params for opt in [*p.opts, *p.secondary_opts]}
    assert {
        "--json",
        "--randomize",
        "--no-randomize",
        "--objective",
    } <= options and "--as-json" not in options


class _Objective:
    option_specs: tuple = ()

    def __init__(self, name: str, options: tuple = ()):
        self.name, self.option_specs = name, options


def test_default_objectives_are_the_installed_ones_without_options(monkeypatch):
    """Every installed objective that declares no options, in each plugin's own order: a
    third-party objective alone is trained by default; a configurable one (a weighted sum)
    only when named."""
    registry = Registry()
    for name, options, dist in (
        ("zeta", (), "coadapt"),
        ("weighted", ("weights",), "coadapt"),
        ("alpha", (), "coadapt"),
        ("theirs", (), "another-dist"),
    ):
        cls = type(name, (), {"name": name, "option_specs": options})
        registry.entries["objective"][name] = PluginInfo("objective", name, cls, dist, "0", "test")
    monkeypatch.setattr("coadapt_core.plugins.get_registry", lambda refresh=False: registry)
    assert train_setup.default_objectives() == ["theirs", "zeta", "alpha"]
