"""Meta-test: the core (coadapt_core) names no built-in plugin, so a third-party robot,
simulator, optimizer or objective is served exactly like a built-in one.

The names looked for are those of every plugin the `coadapt` distribution itself registers
(robots, simulators, optimizers, objectives; read from the registry, so a new built-in is
covered the day it lands) and the options and choices those plugins declare. Scanned, in
every core module:

- imports: of `coadapt_plugins`, or of a module named like a built-in (`import mujoco`);
- identifiers (names, attributes, functions, classes, arguments, keywords): one whose
  `_`-separated parts hold a built-in robot, simulator or optimizer name (`bo_storage`,
  `MUJOCO_GL`, a variable `pso`);
- strings that are values (no whitespace: keys, defaults, lists, option names): one whose
  parts, split at `,=:;/|.()[]`, hold a built-in's name or one of their declared options or
  choices (`'torque'`, `'tracking,power,torque'`, `'inertia'`, `'tpe'`); a built-in robot,
  simulator or optimizer name is found inside `_`-joined words too (`'bo_sampler'`).

Not scanned: docstrings and prose (strings with whitespace: help texts and messages, which
may give an example), and identifiers made of the objective names: tracking, power and
torque are also ordinary words of the task (joint torque, velocity tracking), so a variable
`joint_torque` is no finding, a string `'torque'` is. Option names that are ordinary words of
the core too (`weights`, `storage`) are left out.

KNOWN_DEBT lists findings that another part of issue 27 removes (module -> why and which
part); it may only shrink: the lead removes an entry when that part has merged. EXEMPT lists
words that look like a built-in's but are the core's own, each with why. Every other core
module, present or future, must be clean."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: the built-ins, should the registry not say (it always does where coadapt is installed)
FALLBACK = {
    "kuafu",
    "mujoco",
    "pybullet",
    "pso",
    "mixed-pso",
    "bo",
    "nsga2",
    "tracking",
    "power",
    "torque",
    "composite",
}
#: option names of built-ins that are ordinary words of the core as well
CORE_WORDS = {"weights", "storage"}

#: module -> (the findings it still has, why, the part of issue 27 that removes them)
KNOWN_DEBT: dict[str, str] = {}

#: (module, word) -> why it is the core's own word, not a built-in's
EXEMPT: dict[tuple[str, str], str] = {
    (
        "coadapt_core/methods.py",
        "bo",
    ): "the bo-specialized method (the paper's Table 7 baseline, labelled 'BO') and its "
    "setting bo_designs: a method of the core; it asks for a sequential optimizer, "
    "not for the bo plugin",
    (
        "coadapt_core/coadapt/config.py",
        "bo",
    ): "bo_designs, the bo-specialized method's setting (see methods.py)",
    (
        "coadapt_core/coadapt/presets.py",
        "bo",
    ): "bo_designs per preset, the presets moved out of config.py (see config.py)",
    (
        "coadapt_core/task/commands.py",
        "tracking",
    ): "the curriculum's velocity-tracking sum, a word of the task",
}


def builtin_words() -> tuple[set[str], set[str], set[str]]:
    """(robot, simulator and optimizer names; objective names; declared option names and
    choices) of the plugins the coadapt distribution registers."""
    from coadapt_core.plugins import BUILTIN_DISTRIBUTION, load_registry

    proper, objectives, options = set(), set(), set()
    for kind, entries in load_registry().entries.items():
        for name, info in entries.items():
            if info.distribution != BUILTIN_DISTRIBUTION:
                continue
            (objectives if kind == "objective" else proper).add(name)
            for spec in getattr(info.cls, "option_specs", ()):
                options.add(spec.name)
                options.update(str(c) for c in spec.choices or ())
    if not proper | objectives:
        proper, objectives = (
            {n for n in FALLBACK if n not in {"tracking", "power", "torque", "composite"}},
            {"tracking", "power", "torque", "composite"},
        )
    return proper, objectives, options - CORE_WORDS


PROPER, OBJECTIVES, OPTIONS = builtin_words()


def docstring_ids(tree: ast.AST) -> set[int]:
    """id() of every docstring constant of a parsed module (module, class, function)."""
    out = set()
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if (
            isinstance(node, ast.Module | ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef)
            and body
        ):
            first = body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                out.add(id(first.value))
    return out


def string_constants(tree: ast.AST) -> list[ast.Constant]:
    """The string constants of a parsed module that are not docstrings."""
    docstrings = docstring_ids(tree)
    return [
        node
        for node in ast.walk(tree)
        if isinstance(node, ast.Constant)
        and isinstance(node.value, str)
        and id(node) not in docstrings
    ]


def value_words(text: str) -> set[str]:
    """The built-in words a value string holds (see the module's docstring)."""
    lowered = text.lower()
    whole = set(re.split(r"[,=:;/|.()\[\]]+", lowered))
    parts = set(re.findall(r"[a-z0-9]+(?:-[a-z0-9]+)*", lowered.replace("_", " ")))
    return (whole & (PROPER | OBJECTIVES | OPTIONS)) | (parts & PROPER)


def identifier_words(name: str) -> set[str]:
    return set(name.lower().split("_")) & PROPER


def _identifier(node: ast.AST) -> str | None:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute | ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
        return node.attr if isinstance(node, ast.Attribute) else node.name
    if isinstance(node, ast.arg | ast.keyword):
        return node.arg
    return None


def findings(path: Path, rel: str = "") -> list[str]:
    tree = ast.parse(path.read_text())
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import | ast.ImportFrom):
            modules = [a.name for a in node.names] + [getattr(node, "module", None) or ""]
            if any(m.startswith("coadapt_plugins") for m in modules):
                out.append(f"{node.lineno}: imports coadapt_plugins")
            elif any(m.split(".")[0] in PROPER for m in modules):
                out.append(
                    f"{node.lineno}: imports "
                    f"{', '.join(m for m in modules if m.split('.')[0] in PROPER)}"
                )
            continue
        name = _identifier(node)
        words = identifier_words(name) if name else set()
        words -= {w for w in words if (rel, w) in EXEMPT}
        if words:
            out.append(f"{node.lineno}: {name} names {', '.join(sorted(words))}")
    for node in string_constants(tree):
        if "coadapt_plugins" in node.value:
            out.append(f"{node.lineno}: {node.value!r}")
        elif not re.search(r"\s", node.value):
            words = {w for w in value_words(node.value) if (rel, w) not in EXEMPT}
            if words:
                out.append(f"{node.lineno}: {node.value!r} names {', '.join(sorted(words))}")
    return out


def core_modules() -> list[tuple[str, Path]]:
    return [
        (p.relative_to(ROOT).as_posix(), p) for p in sorted((ROOT / "coadapt_core").rglob("*.py"))
    ]


def test_the_builtins_are_read_from_the_registry():
    assert {"kuafu", "mujoco", "pybullet", "pso", "bo"} <= PROPER
    assert {"tracking", "power", "torque"} <= OBJECTIVES
    assert {"inertia", "c1", "c2", "tpe", "study_name"} <= OPTIONS


def test_core_modules_name_no_builtin_plugin():
    dirty = {}
    for rel, path in core_modules():
        if rel not in KNOWN_DEBT and (found := findings(path, rel)):
            dirty[rel] = found
    assert not dirty, f"core modules name built-in plugins: {dirty}"


def test_known_debt_is_still_debt():
    """A module cleaned up leaves the list (so the list only ever shrinks)."""
    for rel in KNOWN_DEBT:
        path = ROOT / rel
        assert path.exists() and findings(path, rel), (
            f"{rel} is clean now: remove it from KNOWN_DEBT"
        )


def test_every_exemption_is_still_needed():
    for rel, word in EXEMPT:
        path = ROOT / rel
        assert path.exists(), rel
        in_values = any(
            word in value_words(n.value) for n in string_constants(ast.parse(path.read_text()))
        )
        in_names = any(word in identifier_words(n) for n in _identifiers(path))
        assert in_values or in_names, f"{rel}: '{word}' is no longer used: remove it from EXEMPT"


def _identifiers(path: Path) -> list[str]:
    return [n for n in (_identifier(node) for node in ast.walk(ast.parse(path.read_text()))) if n]


def test_the_scan_finds_planted_names(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text(
        '"""Mentions kuafu in a docstring, which is fine."""\n'
        "from coadapt_plugins.robots import kuafu\n"
        'def f(name="mixed-pso", objective="torque"):\n'
        '    return {"bo_sampler": "tpe", "objectives": "tracking,power,torque"}\n'
        "import mujoco\n"
        "pso_inertia = 0.9\n"
        'help = "Objective, e.g. torque (prose is documentation)"\n'
        "joint_torque = 1.0  # a word of the task\n"
    )
    assert findings(bad) == [
        "2: imports coadapt_plugins",
        "5: imports mujoco",
        "6: pso_inertia names pso",
        "3: 'mixed-pso' names mixed-pso",
        "3: 'torque' names torque",
        "4: 'bo_sampler' names bo",
        "4: 'tpe' names tpe",
        "4: 'tracking,power,torque' names power, torque, tracking",
    ]
