"""The recorded signature of the plugin interfaces (`coadapt_core.plugin_api` holds the
version and the rules comparing two signatures).

`interface_signature()` describes everything a plugin is written against; `record(path)`
adds it to the history file a test compares with (`tests/core/plugin_api_signature.json`),
refusing a change that `PLUGIN_API_VERSION` does not account for:

    python -m coadapt_core.api_signature tests/core/plugin_api_signature.json [--amend]

Kept apart from `coadapt_core.plugin_api` (which the registry imports) because describing
the interfaces imports all of them, the conformance suites included.
"""

from __future__ import annotations

import inspect
import json
import sys
from pathlib import Path

from coadapt_core import plugin_api

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
        if (
            name.startswith("_")
            and name != "__init__"
            and name not in abstract
            and name not in OVERRIDABLE
        ):
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
            if hasattr(type(value), "__get__"):  # resolved when read (`TorchDtype`): record
                value = getattr(cls, name)  # what a subclass reads, not the descriptor
            text = (
                repr(value)
                if isinstance(value, int | float | str | bool | tuple | type(None))
                else type(value).__name__
            )
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
    for cls in (
        robot.Robot,
        simulator.Simulator,
        optimizer.Optimizer,
        objective.Objective,
        design_space.DesignSpace,
        actuation.DelayLine,
        randomization.RandomizationConfig,
    ):
        sig[f"{cls.__module__}.{cls.__qualname__}"] = _members(cls)
    for cls in (
        objective.StepBatch,
        robot.RobotModel,
        robot.Leg,
        robot.Mirror,
        robot.Finding,
        robot.ValidationReport,
        simulator.SimState,
        options.PluginOption,
        randomization.EnvParams,
        design_space.Continuous,
        design_space.Discrete,
    ):
        sig[f"{cls.__module__}.{cls.__qualname__} (fields)"] = _fields(cls)
    sig["coadapt_core.hookspecs"] = {
        name: f"hook{inspect.signature(fn)}"
        for name, fn in vars(hookspecs).items()
        if name.startswith("coadapt_register_")
    }
    sig["functions"] = {
        f"{fn.__module__}.{fn.__name__}": f"function{inspect.signature(fn)}"
        for fn in (
            actuation.pd_torque,
            simulator.spawn_base_height,
            simulator.quat_rotate,
            options.resolve_options,
        )
    }
    sig["constants"] = {"coadapt_core.optimizer.SEED_LIMIT": repr(optimizer.SEED_LIMIT)}
    for name in testing.__all__:  # the conformance suites: a plugin's tests inherit them
        suite = getattr(testing, name)
        sig[f"coadapt_core.testing.{name}"] = {
            attr: f"test{inspect.signature(fn)}"
            if attr.startswith("test_")
            else f"fixture{inspect.signature(fn)}"
            for klass in reversed(suite.__mro__)
            if klass is not object
            for attr, fn in vars(klass).items()
            if inspect.isfunction(fn) and not attr.startswith("_")
        }
    return {k: dict(sorted(v.items())) for k, v in sorted(sig.items())}


def record(path: str | Path, *, amend: bool = False) -> str:
    """Add this version's signature to the history file at `path` (a new entry when
    `PLUGIN_API_VERSION` is new; `amend` replaces the last entry of an unreleased version).
    Refuses (ValueError) a change that the version does not account for."""
    path = Path(path)
    history = json.loads(path.read_text()) if path.exists() else {"history": []}
    entries = history["history"]
    version = plugin_api.PLUGIN_API_VERSION
    entry = {"version": version, "signature": interface_signature()}
    if entries and entries[-1]["version"] == version:
        if entries[-1]["signature"] == entry["signature"]:
            return "unchanged"
        if not amend:
            raise ValueError(
                f"the interfaces changed but PLUGIN_API_VERSION is still {version}: raise it "
                "(or pass --amend while this version is unreleased)"
            )
        entries.pop()
    if entries:
        problem = plugin_api.bump_problem(
            entries[-1]["version"], entries[-1]["signature"], entry["version"], entry["signature"]
        )
        if problem:
            raise ValueError(problem)
    entries.append(entry)
    path.write_text(json.dumps(history, indent=1, sort_keys=True) + "\n")
    return "recorded"


if __name__ == "__main__":  # python -m coadapt_core.api_signature PATH [--amend]
    args = sys.argv[1:]
    try:
        print(record(next(a for a in args if not a.startswith("--")), amend="--amend" in args))
    except (ValueError, StopIteration) as exc:
        print(f"error: {exc or 'give the signature file'}", file=sys.stderr)
        sys.exit(2)
