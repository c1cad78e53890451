"""Meta-tests (datasette style): every hook is documented and exercised, every CLI command
has a page, and CI runs the README's test command."""

from __future__ import annotations

import inspect
import re
from pathlib import Path

import pytest

from coadapt_core import hookspecs
from coadapt_core.plugins import KINDS, load_registry

ROOT = Path(__file__).resolve().parents[1]
HOOKS = sorted(
    name
    for name, obj in inspect.getmembers(hookspecs, inspect.isfunction)
    if name.startswith("coadapt_")
)


def test_hookspecs_are_the_four_kinds():
    assert sorted(hook for hook, _ in KINDS.values()) == HOOKS


@pytest.mark.parametrize("hook", HOOKS)
def test_every_hook_documented(hook):
    text = (ROOT / "docs" / "plugins.md").read_text()
    assert re.search(rf"^### {hook}$", text, re.M), f"docs/plugins.md lacks a '### {hook}' section"


@pytest.mark.parametrize("hook", HOOKS)
def test_every_hook_exercised(hook, example_plugin_site, monkeypatch):
    """Some installed plugin (built-in or the example) implements the hook and the registry
    gets at least one class from it."""
    monkeypatch.syspath_prepend(str(example_plugin_site))
    monkeypatch.delenv("COADAPT_LOAD_PLUGINS", raising=False)
    registry = load_registry()
    kind = next(k for k, (h, _) in KINDS.items() if h == hook)
    assert registry.names(kind), f"no plugin provides {hook}"


def _commands() -> list[str]:
    from typer.main import get_command

    from coadapt_core.cli import app

    return sorted(get_command(app).commands)


def test_every_cli_command_has_a_page():
    missing = [c for c in _commands() if not (ROOT / "docs" / "cli" / f"{c}.md").exists()]
    assert not missing, f"docs/cli/ lacks pages for {missing}"


def _quickstart() -> list[str]:
    text = (ROOT / "README.md").read_text()
    block = re.search(r"## Quickstart.*?```bash\n(.*?)```", text, re.S)
    assert block, "README.md has a Quickstart with a bash block"
    return [line for line in block.group(1).splitlines() if line.strip()]


def test_readme_quickstart_is_two_lines_run_and_test():
    lines = _quickstart()
    assert len(lines) == 2
    assert lines[0].endswith("coadapt run --optimizer pso --sim mujoco")
    assert re.search(r"&& pytest( |$)", lines[1])


def test_ci_runs_the_readme_test_line_verbatim():
    assert _quickstart()[1] in (ROOT / ".ci" / "run").read_text()
