"""The benchmarks stand on the installed package alone: no file under benchmarks/ imports
the test suite (`tests`), whose fakes and helpers are not shipped; what a benchmark needs
from them lives in `coadapt_core.testing` (the analytic backend) or in the benchmark."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def imported_modules(source: str) -> list[str]:
    """Every module a Python source imports, at any depth (function-level imports too)."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.append(node.module)
        elif (
            isinstance(node, ast.Call)
            and getattr(node.func, "attr", getattr(node.func, "id", "")) == "import_module"
        ):
            out += [
                a.value
                for a in node.args[:1]
                if isinstance(a, ast.Constant) and isinstance(a.value, str)
            ]
    return out


def imports_tests(source: str) -> list[str]:
    return [m for m in imported_modules(source) if m == "tests" or m.startswith("tests.")]


def test_no_benchmark_imports_the_tests():
    found = {}
    for path in sorted((ROOT / "benchmarks").rglob("*.py")):
        if bad := imports_tests(path.read_text()):
            found[path.relative_to(ROOT).as_posix()] = bad
    for path in sorted(
        (ROOT / "benchmarks").rglob("*.sh")
    ):  # python -m tests... or -c "import tests..."
        text = path.read_text()
        if "-m tests." in text or "import tests" in text or "from tests" in text:
            found[path.relative_to(ROOT).as_posix()] = ["tests"]
    assert not found, f"benchmarks import the test suite: {found}"


def test_the_check_finds_an_import_of_the_tests():
    source = (
        "import json\nfrom coadapt_core.testing.analytic import SPACE\n\ndef f():\n"
        "    from tests.fakes.analytic import AnalyticBackend\n    import tests\n"
        "    importlib.import_module('tests.fakes')\n"
    )
    assert imports_tests(source) == ["tests.fakes.analytic", "tests", "tests.fakes"]
