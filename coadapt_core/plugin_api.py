"""The plugin API's version, and what a plugin declares to say which version it was written for.

The plugin interfaces — the four base classes (`Robot`, `Simulator`, `Optimizer`,
`Objective`), the records they exchange (`StepBatch`, `RobotModel`, `SimState`, ...), the
design spaces, the shared actuation, the hooks and the conformance suites — carry one
semantic version, `PLUGIN_API_VERSION`: the major number changes when a plugin written for
the previous one may stop working (a field removed, a contract changed), the minor one when
something is only added.

A plugin declares the version it was written for, either for every class its hook module
registers (a module attribute of the module named by its entry point)::

    COADAPT_PLUGIN_API = "2.0"

or per class (`plugin_api = "2.0"`, a class attribute; it wins over the module's). The
registry then

- loads a plugin written for this major version and a minor version up to this one;
- refuses one written for an older major version with one line naming what changed since and
  where the migration guide is (docs/plugins.md#migration); it is listed as broken, and a
  command that names it exits 2 with that line;
- refuses one written for a newer version (upgrade coadapt), or declaring something that is
  not a version;
- loads a plugin that declares nothing (written before versions were declared) and
  `coadapt plugins` says so.

`tests/core/plugin_api_signature.json` records the interfaces' signatures at each version
(`interface_signature()`); a test fails when they change without the version changing as
much as the change requires (`required_bump`). After a deliberate change: raise
`PLUGIN_API_VERSION`, add the change to `BREAKING_CHANGES` (major) and CHANGELOG.md, then
`python -m coadapt_core.plugin_api tests/core/plugin_api_signature.json`.
"""

from __future__ import annotations

import inspect
import json
import re
import sys
from pathlib import Path

#: the version of the plugin interfaces (semantic: major.minor.patch)
PLUGIN_API_VERSION = "2.0.0"
#: where a plugin author reads what changed and how to adapt
MIGRATION_DOC = "docs/plugins.md#migration"
#: the module attribute of a plugin's hook module declaring the version its classes target
MODULE_ATTRIBUTE = "COADAPT_PLUGIN_API"
#: the class attribute declaring it for one class (wins over the module's)
CLASS_ATTRIBUTE = "plugin_api"

#: what each major version broke, one short clause each (the refusal line lists them).
#: Version 1 is the interface before versions were declared.
BREAKING_CHANGES: dict[int, tuple[str, ...]] = {
    2: (
        "StepBatch has no `action` field (read `joint_targets`)",
        "`initial_designs` is a constructor argument checked by Optimizer.__init__, not an option",
        "an optimizer's first ask must return `initial_designs` (a run warns at its start when it does not)",
        "undeclared options are refused (declare them in `option_specs`)",
        "optimizer state is plain JSON through state_dict/load_state_dict, never a pickle",
        "seeds are any integer in [0, 2**63) (32-bit libraries get `self.seed32`)",
    ),
}

_VERSION = re.compile(r"^\s*v?(\d+)(?:\.(\d+))?(?:\.(\d+))?\s*$")


def parse_version(value: object) -> tuple[int, int, int]:
    """'2', '2.1', '2.1.3' (or an int) as (major, minor, patch); ValueError otherwise."""
    if isinstance(value, bool):
        raise ValueError(f"not a version: {value!r}")
    if isinstance(value, int):
        return (value, 0, 0)
    found = _VERSION.match(str(value)) if isinstance(value, str) else None
    if found is None:
        raise ValueError(f"not a version: {value!r}")
    return tuple(int(g or 0) for g in found.groups())  # type: ignore[return-value]


def current() -> tuple[int, int, int]:
    return parse_version(PLUGIN_API_VERSION)


def declared_api(cls: type, module: object | None = None) -> str | None:
    """The plugin API version `cls` declares (its class attribute, else its hook module's),
    as text; None when neither declares one."""
    value = getattr(cls, CLASS_ATTRIBUTE, None)
    if value is None and module is not None:
        value = getattr(module, MODULE_ATTRIBUTE, None)
    return None if value is None else str(value)


def changes_since(major: int) -> list[str]:
    """The breaking changes of every major version after `major`, up to this one."""
    return [c for m in sorted(BREAKING_CHANGES) if major < m <= current()[0] for c in BREAKING_CHANGES[m]]


def api_problem(declared: str | None) -> str | None:
    """Why a plugin declaring `declared` cannot be loaded, in one clause; None when it can
    (undeclared included)."""
    if declared is None:
        return None
    try:
        major, minor, _ = parse_version(declared)
    except ValueError:
        return (f"declares plugin API {declared!r}, which is not a version; declare the version it was written "
                f"for, e.g. {MODULE_ATTRIBUTE} = \"{current()[0]}.{current()[1]}\"")
    have_major, have_minor, _ = current()
    if major < have_major:
        changed = "; ".join(changes_since(major)) or "see the changelog"
        return (f"was written for coadapt plugin API {major}.x and this coadapt has {PLUGIN_API_VERSION}, which "
                f"changed: {changed}; adapt it as {MIGRATION_DOC} says, then declare "
                f"{MODULE_ATTRIBUTE} = \"{have_major}.{have_minor}\"")
    if major > have_major or minor > have_minor:
        return (f"needs coadapt plugin API {major}.{minor}, newer than this coadapt's {PLUGIN_API_VERSION}: "
                "upgrade coadapt (pip install -U coadapt)")
    return None


def undeclared_note(distribution: str) -> str:
    return (f"note: plugin distribution {distribution} declares no plugin API version (this coadapt's is "
            f"{PLUGIN_API_VERSION}); check it against {MIGRATION_DOC} and declare "
            f"{MODULE_ATTRIBUTE} = \"{current()[0]}.{current()[1]}\" in its hook module")


# -- the recorded signature of the interfaces -----------------------------------------------
#: private methods a plugin overrides (documented in docs/plugins.md): part of the interface
OVERRIDABLE = frozenset({"_restore"})


def _members(cls: type) -> dict[str, str]:
    """What a subclass sees of `cls`: methods (signature, abstract or not), properties, class
    attributes (annotation and value), defined in `cls` itself."""
    out: dict[str, str] = {}
    abstract = getattr(cls, "__abstractmethods__", frozenset())
    annotations = inspect.get_annotations(cls)
    for name, value in cls.__dict__.items():
        if name.startswith("__") and name != "__init__":
            continue
        if name.startswith("_") and name != "__init__" and name not in abstract and name not in OVERRIDABLE:
            continue  # the base class's own helpers
        if isinstance(value, staticmethod | classmethod):
            value = value.__func__
            kind = "classmethod" if isinstance(cls.__dict__[name], classmethod) else "staticmethod"
        else:
            kind = "method"
        if isinstance(value, property):
            out[name] = "property"
        elif inspect.isfunction(value):
            tag = "abstract " if name in abstract else ""
            out[name] = f"{tag}{kind}{inspect.signature(value)}"
        elif not callable(value):
            text = repr(value) if isinstance(value, int | float | str | bool | tuple | type(None)) else type(value).__name__
            out[name] = f"attribute: {annotations.get(name, '')} = {text}"
    for name, annotation in annotations.items():
        out.setdefault(name, f"attribute: {annotation}")
    return dict(sorted(out.items()))


def _fields(cls: type) -> dict[str, str]:
    import dataclasses

    out = {}
    for f in dataclasses.fields(cls):
        required = f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        out[f.name] = f"field: {f.type}" + (" (required)" if required else " (optional)")
    return out


def interface_signature() -> dict[str, dict[str, str]]:
    """`{interface: {member: description}}` of everything a plugin is written against."""
    from coadapt_core import design_space, hookspecs, objective, optimizer, options, robot, testing
    from coadapt_core.physics import actuation, randomization, simulator

    sig: dict[str, dict[str, str]] = {}
    for cls in (robot.Robot, simulator.Simulator, optimizer.Optimizer, objective.Objective,
                design_space.DesignSpace, actuation.DelayLine, randomization.RandomizationConfig):
        sig[f"{cls.__module__}.{cls.__qualname__}"] = _members(cls)
    for cls in (objective.StepBatch, robot.RobotModel, robot.Leg, robot.Finding, robot.ValidationReport,
                simulator.SimState, options.PluginOption, randomization.EnvParams, design_space.Continuous,
                design_space.Discrete):
        sig[f"{cls.__module__}.{cls.__qualname__} (fields)"] = _fields(cls)
    sig["coadapt_core.hookspecs"] = {
        name: f"hook{inspect.signature(fn)}" for name, fn in vars(hookspecs).items() if name.startswith("coadapt_register_")
    }
    sig["functions"] = {
        f"{fn.__module__}.{fn.__name__}": f"function{inspect.signature(fn)}"
        for fn in (actuation.pd_torque, simulator.spawn_base_height, simulator.quat_rotate, options.resolve_options)
    }
    sig["constants"] = {"coadapt_core.optimizer.SEED_LIMIT": repr(optimizer.SEED_LIMIT)}
    for name in testing.__all__:  # the conformance suites: a plugin's tests inherit them
        suite = getattr(testing, name)
        sig[f"coadapt_core.testing.{name}"] = {
            attr: f"test{inspect.signature(fn)}" if attr.startswith("test_") else f"fixture{inspect.signature(fn)}"
            for klass in reversed(suite.__mro__) if klass is not object
            for attr, fn in vars(klass).items() if inspect.isfunction(fn) and not attr.startswith("_")
        }
    return {k: dict(sorted(v.items())) for k, v in sorted(sig.items())}


def _flat(signature: dict[str, dict[str, str]]) -> dict[str, str]:
    return {f"{where}::{name}": text for where, members in signature.items() for name, text in members.items()}


def signature_changes(old: dict[str, dict[str, str]], new: dict[str, dict[str, str]]) -> dict[str, list[str]]:
    """{'removed': [...], 'changed': [...], 'added': [...]} between two signatures."""
    a, b = _flat(old), _flat(new)
    return {
        "removed": sorted(k for k in a if k not in b),
        "changed": sorted(k for k in a if k in b and a[k] != b[k]),
        "added": sorted(k for k in b if k not in a),
    }


def required_bump(old: dict[str, dict[str, str]], new: dict[str, dict[str, str]]) -> str | None:
    """'major' when a plugin written against `old` may break under `new` (something removed
    or changed, an abstract method or a required record field added), 'minor' when things
    were only added, None when nothing changed."""
    diff = signature_changes(old, new)
    flat = _flat(new)
    breaking_additions = [k for k in diff["added"] if flat[k].startswith("abstract ") or flat[k].endswith("(required)")]
    if diff["removed"] or diff["changed"] or breaking_additions:
        return "major"
    return "minor" if diff["added"] else None


def bump_of(old_version: str, new_version: str) -> str | None:
    """'major', 'minor', 'patch' or None: how far `new_version` is above `old_version`
    ('backwards' when it is below)."""
    a, b = parse_version(old_version), parse_version(new_version)
    if b < a:
        return "backwards"
    if b[0] > a[0]:
        return "major"
    if b[1] > a[1]:
        return "minor"
    if b[2] > a[2]:
        return "patch"
    return None


_RANK = {None: 0, "patch": 1, "minor": 2, "major": 3}


def bump_problem(old_version: str, old_sig: dict, new_version: str, new_sig: dict) -> str | None:
    """Why going from (old_version, old_sig) to (new_version, new_sig) is not a correct
    version bump; None when it is."""
    need = required_bump(old_sig, new_sig)
    have = bump_of(old_version, new_version)
    if have == "backwards":
        return f"version {new_version} is below {old_version}"
    if _RANK[have] < _RANK[need]:
        diff = signature_changes(old_sig, new_sig)
        shown = "; ".join(f"{kind}: {', '.join(keys[:5])}{' ...' if len(keys) > 5 else ''}"
                          for kind, keys in diff.items() if keys)
        return (f"the plugin interfaces changed ({shown}) and need a {need} version bump over {old_version}; "
                f"the version is {new_version}")
    return None


def record(path: str | Path, *, amend: bool = False) -> str:
    """Add this version's signature to the history file at `path` (a new entry when
    `PLUGIN_API_VERSION` is new; `amend` replaces the last entry of an unreleased version).
    Refuses (ValueError) a change that the version does not account for."""
    path = Path(path)
    history = json.loads(path.read_text()) if path.exists() else {"history": []}
    entries = history["history"]
    entry = {"version": PLUGIN_API_VERSION, "signature": interface_signature()}
    if entries and entries[-1]["version"] == PLUGIN_API_VERSION:
        if entries[-1]["signature"] == entry["signature"]:
            return "unchanged"
        if not amend:
            raise ValueError(
                f"the interfaces changed but PLUGIN_API_VERSION is still {PLUGIN_API_VERSION}: raise it "
                "(or pass --amend while this version is unreleased)")
        entries.pop()
    if entries:
        problem = bump_problem(entries[-1]["version"], entries[-1]["signature"], entry["version"], entry["signature"])
        if problem:
            raise ValueError(problem)
    entries.append(entry)
    path.write_text(json.dumps(history, indent=1, sort_keys=True) + "\n")
    return "recorded"


if __name__ == "__main__":  # python -m coadapt_core.plugin_api PATH [--amend]
    args = sys.argv[1:]
    try:
        print(record(next(a for a in args if not a.startswith("--")), amend="--amend" in args))
    except (ValueError, StopIteration) as exc:
        print(f"error: {exc or 'give the signature file'}", file=sys.stderr)
        sys.exit(2)
