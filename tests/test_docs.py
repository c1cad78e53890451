"""Meta-tests (datasette style): every hook is documented and exercised, every CLI command
has a page, CI runs the README's test command, and docs/status.md stays one short table
whose every row links to the page with its details."""

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


#: docs/status.md: a newcomer reads it in a minute (issue 61: it had grown to 2 310 words)
STATUS_WORDS, STATUS_ROW_WORDS = 1000, 50


def heading_anchors(page: Path) -> set[str]:
    """The anchors of a Markdown page's headings, as GitHub makes them."""
    out = set()
    for line in page.read_text().splitlines():
        if line.startswith("#"):
            title = line.lstrip("#").strip().lower()
            out.add(re.sub(r"[^\w\- ]", "", title).replace(" ", "-"))
    return out


def test_status_is_one_short_table_each_row_a_headline_and_a_link():
    page = ROOT / "docs" / "status.md"
    text = page.read_text()
    assert len(text.split()) <= STATUS_WORDS, f"docs/status.md: {len(text.split())} words"
    lines = text.splitlines()
    table = [i for i, line in enumerate(lines) if line.startswith("|")]
    assert table == list(range(table[0], table[-1] + 1)), "one table, no second one"
    rows = [lines[i] for i in table[2:]]
    assert len(rows) >= 20
    for row in rows:
        cells = [c.strip() for c in row.strip().strip("|").split(" | ")]
        assert len(cells) == 3, row
        assert len(cells[1].split()) <= STATUS_ROW_WORDS, f"a long row: {cells[0]}"
        links = re.findall(r"\]\(([^)]+)\)", cells[2])
        assert links, f"no link in the row {cells[0]}"
        for link in links:
            path, _, anchor = link.partition("#")
            target = (page.parent / path).resolve()
            assert target.is_file(), f"{cells[0]}: {link} is no file"
            assert not anchor or anchor in heading_anchors(target), f"{cells[0]}: {link}"
