"""`--help` of every command at 80 columns: no option name is cut, no line is wider than
the terminal, and defaults are shown in one style ([default: X], never "(default X)")."""

from __future__ import annotations

import re

import pytest
import typer

from coadapt_core.cli import app, main


def _commands(command, path=()):
    subs = getattr(command, "commands", None)
    if subs:
        for name, sub in subs.items():
            yield from _commands(sub, (*path, name))
    else:
        yield path, command


COMMANDS = list(_commands(typer.main.get_command(app)))


def test_every_command_is_covered():
    names = {" ".join(p) for p, _ in COMMANDS}
    assert {
        "run",
        "train",
        "eval",
        "grid",
        "report",
        "landscape",
        "export",
        "plugins",
        "robot show",
    } <= names


@pytest.mark.parametrize("path", [p for p, _ in COMMANDS], ids=[" ".join(p) for p, _ in COMMANDS])
def test_help_at_80_columns_shows_every_option_whole(path, monkeypatch, capsys):
    monkeypatch.setenv("COLUMNS", "80")
    monkeypatch.setenv("TERM", "dumb")
    # `run --help` lists the common options; `--help-all` every one (tests/core/test_everyday.py)
    assert main([*path, "--help-all" if path == ("run",) else "--help"]) == 0
    text = capsys.readouterr().out
    command = dict(COMMANDS)[path]
    for param in command.params:
        if getattr(param, "param_type_name", "") != "option" or param.hidden:
            continue
        for name in [*param.opts, *param.secondary_opts]:
            assert re.search(rf"(^|[\s,/]){re.escape(name)}([\s,/=]|$)", text, re.M), (
                f"{name} cut or missing"
            )
    assert "…" not in text
    assert max(len(line) for line in text.splitlines()) <= 80
    assert not re.search(r"\(default[: ]", text), "a default written as '(default X)'"
