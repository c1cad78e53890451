"""The plugin API's version, and what a plugin declares to say which version it was written for.

The plugin interfaces — the four base classes (`Robot`, `Simulator`, `Optimizer`,
`Objective`), the records they exchange (`StepBatch`, `RobotModel`, `SimState`, ...), the
design spaces, the shared actuation, the hooks and the conformance suites — carry one
semantic version, `PLUGIN_API_VERSION`: the major number changes when a plugin written for
the previous one may stop working (a field removed, a contract changed), the minor one when
something is only added.

A plugin declares the version it was written for, either for every class its hook module
registers (a module attribute of the module named by its entry point)::

    COADAPT_PLUGIN_API = "2.1"

or per class (`plugin_api = "2.1"`, a class attribute; it wins over the module's). The
registry then

- loads a plugin written for this major version and a minor version up to this one;
- refuses one written for an older major version with one line naming what changed since and
  where the migration guide is (docs/plugins.md#migration); it is listed as broken, and a
  command that names it exits 2 with that line;
- refuses one written for a newer version (upgrade coadapt), or declaring something that is
  not a version;
- takes a plugin that declares nothing as written before versions were declared, that is
  for 1.x, and refuses it the same way (its line says it declared nothing).

`tests/core/plugin_api_signature.json` records the interfaces' signatures at each version
(`coadapt_core.api_signature`); a test fails when they change without the version changing
as much as the change requires (`required_bump`). After a deliberate change: raise
`PLUGIN_API_VERSION`, add the change to `BREAKING_CHANGES` (major) and CHANGELOG.md, then
`python -m coadapt_core.api_signature tests/core/plugin_api_signature.json`.
"""

from __future__ import annotations

import re

#: the version of the plugin interfaces (semantic: major.minor.patch)
PLUGIN_API_VERSION = "2.4.0"
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
        "an optimizer's first ask must return `initial_designs` (a run warns at its start when it "
        "does not)",
        "undeclared options are refused (declare them in `option_specs`)",
        "optimizer state is plain JSON through state_dict/load_state_dict, never a pickle",
        "seeds are any integer in [0, 2**63) (32-bit libraries get `self.seed32`)",
        "RobotModel carries its descriptions in `formats` {format: text}, not `mjcf`/`urdf` fields "
        "(read `model.text('mjcf')`; a simulator declares `model_formats`)",
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
    return [
        c
        for m in sorted(BREAKING_CHANGES)
        if major < m <= current()[0]
        for c in BREAKING_CHANGES[m]
    ]


def _older_major(major: int) -> str:
    """The clause refusing a plugin written for the older major version `major`."""
    have_major, have_minor, _ = current()
    changed = "; ".join(changes_since(major)) or "see the changelog"
    return (
        f"was written for coadapt plugin API {major}.x and this coadapt has "
        f"{PLUGIN_API_VERSION}, which changed: {changed}; adapt it as {MIGRATION_DOC} says, "
        "then declare "
        f'{MODULE_ATTRIBUTE} = "{have_major}.{have_minor}"'
    )


def api_problem(declared: str | None) -> str | None:
    """Why a plugin declaring `declared` cannot be loaded, in one clause; None when it can.
    A plugin declaring nothing was written before versions were declared: for 1.x."""
    if declared is None:
        return (
            "declares no plugin API version, so it is taken as written for 1.x: it "
            + _older_major(1)
        )
    try:
        major, minor, _ = parse_version(declared)
    except ValueError:
        return (
            f"declares plugin API {declared!r}, which is not a version; declare the version it "
            f'was written for, e.g. {MODULE_ATTRIBUTE} = "{current()[0]}.{current()[1]}"'
        )
    have_major, have_minor, _ = current()
    if major < have_major:
        return _older_major(major)
    if major > have_major or minor > have_minor:
        return (
            f"needs coadapt plugin API {major}.{minor}, newer than this coadapt's "
            f"{PLUGIN_API_VERSION}: upgrade coadapt (pip install -U coadapt)"
        )
    return None


# -- comparing recorded signatures (coadapt_core.api_signature records them) ----------------
def _flat(signature: dict[str, dict[str, str]]) -> dict[str, str]:
    return {
        f"{where}::{name}": text
        for where, members in signature.items()
        for name, text in members.items()
    }


def _suite_test(key: str, text: str) -> bool:
    """Whether a flat signature entry is a conformance suite's test method."""
    return key.startswith("coadapt_core.testing.") and text.startswith("test(")


def signature_changes(
    old: dict[str, dict[str, str]], new: dict[str, dict[str, str]]
) -> dict[str, list[str]]:
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
    were only added, None when nothing changed. A conformance suite's test is a check run on
    a plugin, not an interface the plugin calls or implements: removing or renaming one
    breaks no plugin (minor), adding one is minor (the plugin's suite has a check more). A
    record or class that is new altogether breaks nothing, its required fields included."""
    diff = signature_changes(old, new)
    flat_old, flat = _flat(old), _flat(new)
    breaking_additions = [
        k
        for k in diff["added"]
        if (flat[k].startswith("abstract ") or flat[k].endswith("(required)"))
        and k.split("::", 1)[0] in old
    ]
    removed = [k for k in diff["removed"] if not _suite_test(k, flat_old[k])]
    if diff["removed"] and not removed:
        # a check dropped or renamed (and maybe things added): nothing a plugin relies on
        return "minor"
    if removed or diff["changed"] or breaking_additions:
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
        shown = "; ".join(
            f"{kind}: {', '.join(keys[:5])}{' ...' if len(keys) > 5 else ''}"
            for kind, keys in diff.items()
            if keys
        )
        return (
            f"the plugin interfaces changed ({shown}) and need a {need} version bump over "
            f"{old_version}; the version is {new_version}"
        )
    return None
