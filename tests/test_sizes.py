"""Every room reads in one sitting: no function in coadapt_core or the built-in plugins longer
than MAX_FUNCTION lines (a nested function counts inside its parent too) and no module longer
than MAX_MODULE lines (the tree keeps 100 columns, so lines are not squeezed to fit),
except the declaration tables docs/architecture.md names under "Size exceptions" (each with
why). An exception that no longer needs its place must leave the list."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MAX_FUNCTION, MAX_MODULE = 80, 450
PACKAGES = ("coadapt_core", "plugins")


def sizes(root: Path = ROOT) -> tuple[dict[str, int], dict[str, int]]:
    """(module path -> lines, 'path:qualified function' -> lines) over root's PACKAGES."""
    modules, functions = {}, {}
    paths = [path for package in PACKAGES for path in sorted((root / package).rglob("*.py"))]
    for path in paths:
        rel = path.relative_to(root).as_posix()
        text = path.read_text()
        modules[rel] = text.count("\n")
        _visit(ast.parse(text), rel, "", functions)
    return modules, functions


def _visit(node: ast.AST, rel: str, prefix: str, functions: dict[str, int]) -> None:
    """Every function under `node` as 'rel:Outer.inner' -> its lines (classes name the path)."""
    for child in ast.iter_child_nodes(node):
        if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            name = f"{prefix}{child.name}"
            if not isinstance(child, ast.ClassDef):
                functions[f"{rel}:{name}"] = child.end_lineno - child.lineno + 1
            _visit(child, rel, f"{name}.", functions)
        else:
            _visit(child, rel, prefix, functions)


def exceptions() -> dict[str, str]:
    """`path` or `path:function` -> why, from docs/architecture.md's "Size exceptions" list."""
    text = (ROOT / "docs" / "architecture.md").read_text()
    match = re.search(r"^## Size exceptions\n(.*?)(?=^## |\Z)", text, flags=re.M | re.S)
    assert match, 'docs/architecture.md has no "## Size exceptions" section'
    return {
        m.group(1): m.group(2).strip()
        for m in re.finditer(r"^- `([^`]+)`: (.+)$", match.group(1), flags=re.M)
    }


def test_no_function_or_module_is_longer_than_the_limit():
    modules, functions = sizes()
    allowed = exceptions()
    long_modules = {p: n for p, n in modules.items() if n > MAX_MODULE and p not in allowed}
    long_functions = {f: n for f, n in functions.items() if n > MAX_FUNCTION and f not in allowed}
    assert not long_modules, f"modules over {MAX_MODULE} lines: {long_modules}"
    assert not long_functions, f"functions over {MAX_FUNCTION} lines: {long_functions}"


def test_every_exception_is_still_needed_and_says_why():
    modules, functions = sizes()
    for name, why in exceptions().items():
        size = functions.get(name) if ":" in name else modules.get(name)
        assert size is not None, f"size exception {name} names nothing in coadapt_core or plugins"
        limit = MAX_FUNCTION if ":" in name else MAX_MODULE
        assert size > limit, (
            f"size exception {name} is {size} lines, within {limit}: take it off the list"
        )
        assert len(why) > 20, f"size exception {name} needs its reason"


def test_the_measure_finds_a_planted_long_function_and_module(tmp_path):
    core = tmp_path / "coadapt_core" / "room"
    core.mkdir(parents=True)
    body = "            x = 1\n" * 90
    (core / "long.py").write_text(
        "class A:\n    def outer(self):\n        def inner():\n" + body + "        return inner\n"
    )
    (core / "big.py").write_text("y = 0\n" * 451)
    plugin = tmp_path / "plugins" / "robots"
    plugin.mkdir(parents=True)
    (plugin / "big.py").write_text("y = 0\n" * 451)
    modules, functions = sizes(tmp_path)
    assert functions["coadapt_core/room/long.py:A.outer"] == 93 > MAX_FUNCTION
    assert functions["coadapt_core/room/long.py:A.outer.inner"] == 91
    assert modules["coadapt_core/room/big.py"] == 451 > MAX_MODULE
    assert modules["plugins/robots/big.py"] == 451
