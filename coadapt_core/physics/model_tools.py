"""What the core asks of a robot model outside a batched simulation, answered by a simulator
plugin. `Simulator.model_tools` names a module (a dotted path, "" for none) that reads the
robot's model in one of the simulator's `model_formats` and offers:

    link_facts(model) -> dict
        the bodies at the default pose (name, parent, joints, offset from the parent, mass,
        centre of mass, principal inertia), "total_mass", "height" and "lowest_point"
        (the handoff's design sheet; the robot conformance suite's names and mass)
    foot_positions(model, joint_pos) -> ndarray [F, 3]
        each of `model.foot_bodies`' origins in the base frame with the actuated joints at
        `joint_pos` (the order of `model.joint_names`)
    actuated_joints(model) -> list[str | None]
        the joint each actuator drives, in actuator order; None for one that drives no joint
    HANDOFF_CHECK: pathlib.Path | None
        a standalone script that walks a handoff folder's model with its ONNX controller in
        this engine (copied into the folder as check.py; None: the folder has no check.py)
    handoff_usage(rates, model_file) -> str
        the handoff README's section on loading the model and running the controller

The core picks the run's simulator's tools, else those of the first installed simulator that
declares tools and reads one of the model's formats (`tools_for`, which names that
simulator); a robot plugin's conformance suite does the same, so a third-party simulator
that reads a new format brings its own tools and needs no change here.
"""

from __future__ import annotations

import importlib
from types import ModuleType
from typing import Any

from coadapt_core.errors import UserError


def tool_simulators(registry: Any, formats: Any, prefer: str | None = None) -> list[str]:
    """Installed simulators (`prefer` first, then the default one, then by name) that declare
    model tools and read one of `formats` (model format names)."""
    names = registry.names("simulator")
    order = (
        ([prefer] if prefer else []) + ([registry.default("simulator")] if names else []) + names
    )
    wanted = set(formats)
    return [
        n
        for n in dict.fromkeys(order)
        if n in names
        and getattr(registry.get("simulator", n), "model_tools", "")
        and wanted & set(getattr(registry.get("simulator", n), "model_formats", ()))
    ]


def tools_for(registry: Any, model: Any, prefer: str | None = None) -> tuple[str, ModuleType]:
    """(simulator name, model tools module) for `model` (a `RobotModel`): `prefer`'s (a
    simulator name) when it declares tools and reads one of the model's formats, else the
    first other installed simulator's that does; a one-line `UserError` when none does."""
    names = tool_simulators(registry, getattr(model, "formats", {}) or {}, prefer)
    if not names:
        given = ", ".join(sorted(getattr(model, "formats", {}) or {})) or "none"
        raise UserError(
            f"no installed simulator plugin declares model tools (Simulator.model_tools) for the "
            f"model formats {given}",
            field="simulator",
        )
    return names[0], importlib.import_module(str(registry.get("simulator", names[0]).model_tools))
