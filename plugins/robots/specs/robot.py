"""The `Robot` a spec becomes: design spaces, cached models per design, the generic leg IK.

`spec_robot_class(path)` turns a spec file into a `Robot` subclass named by the spec, which
any plugin's `coadapt_register_robots` hook may return (the folders of `COADAPT_ROBOT_PATH`
are registered that way, `discovery`); `folder_robot_class(folder)` names it by its folder
and reads the files on first use (the built-in spec robots: listing them reads nothing).
"""

from __future__ import annotations

import hashlib
from functools import cached_property, lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

from coadapt_core.design_space import Continuous, DesignSpace, Discrete
from coadapt_core.errors import DesignError
from coadapt_core.robot import Leg, Mirror, Robot, RobotModel, ValidationReport

if TYPE_CHECKING:
    import numpy as np
    import torch
    from coadapt_plugins.robots.specs.spec import RobotSpec


class SpecRobot(Robot):
    """A robot described by a spec file (`spec_path`); subclasses name it."""

    spec_path: ClassVar[Path]
    #: the SHA-256 (12 hex) of the spec and model files: the registry's version of the robot,
    #: compared between a Ray driver and its nodes
    plugin_version: ClassVar[str] = ""
    #: a robot found in a user's folder gives way to a plugin's robot of its name
    yields_name: ClassVar[bool] = False

    @cached_property
    def spec(self) -> RobotSpec:
        from coadapt_plugins.robots.specs.spec import read_spec

        return read_spec(self.spec_path)

    @cached_property
    def _built(self):
        from coadapt_plugins.robots.specs.build import SpecBuilder

        return SpecBuilder(self.spec)

    # -- design spaces --------------------------------------------------------------------
    def design_space(self, mixed: bool = False) -> DesignSpace:
        variables: list[Any] = [
            Continuous(p.name, p.low, p.high, unit=p.unit or f"x nominal ({p.nominal:g})")
            for p in self.spec.parameters
        ]
        if mixed:
            kinds = tuple(float(k) for k in sorted(self.spec.motor_types))
            variables += [Discrete(m.name, kinds, unit="type") for m in self.spec.motor_parameters]
        return DesignSpace(variables)

    def nominal_design(self, mixed: bool = False) -> np.ndarray:
        import numpy as np

        values = [p.nominal for p in self.spec.parameters]
        if mixed:
            values += [float(m.nominal) for m in self.spec.motor_parameters]
        return np.array(values, dtype=float)

    def check_design(self, design: np.ndarray) -> np.ndarray:
        import numpy as np

        values = np.atleast_1d(np.asarray(design, dtype=float))
        plain, mixed = self.design_space(False), self.design_space(True)
        if values.ndim != 1 or values.shape[0] not in (plain.dim, mixed.dim):
            accepted = f"{plain.dim} values ({', '.join(plain.names)})"
            if mixed.dim != plain.dim:
                accepted += f" or {mixed.dim} values ({', '.join(mixed.names)})"
            raise DesignError(
                f"{self.name} design needs {accepted}, got {values.size}", field="design"
            )
        values = self.design_space(values.shape[0] != plain.dim).validate(values)
        values[plain.dim :] = np.round(values[plain.dim :])
        return values

    # -- models -----------------------------------------------------------------------------
    def build(self, design: np.ndarray) -> RobotModel:
        import numpy as np
        from coadapt_plugins.robots.specs.spec import DESIGN_DECIMALS

        values = self.check_design(design)
        return self._cached(tuple(float(x) for x in np.round(values, DESIGN_DECIMALS)))

    @lru_cache(maxsize=1024)  # noqa: B019 - one cache per robot instance is what we want
    def _cached(self, key: tuple[float, ...]) -> RobotModel:
        import numpy as np

        return self._built.model(np.array(key))

    def validate(self, design: np.ndarray) -> ValidationReport:
        from coadapt_plugins.robots.specs.validation import validate_spec_model

        return validate_spec_model(self, self.build(design))

    def shipped_policy(self, terrain: str, mixed: bool = False) -> Path | None:
        """`policies/<terrain>.pt` (`<terrain>-mixed.pt`) in the robot's own folder, beside
        its spec: a spec robot ships a policy as data too."""
        path = self.spec_path / "policies" / (f"{terrain}-mixed.pt" if mixed else f"{terrain}.pt")
        return path if path.is_file() else None

    def legs(self) -> list[Leg]:
        return [Leg(leg.name, leg.phase) for leg in self.spec.legs]

    def mirror(self) -> Mirror:
        """Derived from the legs' names and the joints' axes (`mirror.derive_mirror`); a
        one-line `UserError` saying what does not pair when the robot is not symmetric."""
        from coadapt_plugins.robots.specs.mirror import derive_mirror

        return derive_mirror(self)

    # -- leg kinematics -------------------------------------------------------------------
    def default_foot_positions(self, designs: torch.Tensor) -> torch.Tensor:
        """[n, L, 3] each foot body's origin relative to its leg's hip point at the standing
        pose, base frame (`kinematics`; a pose solved per design: its targets)."""
        import torch

        if self.spec.standing_share is not None:  # the pose solved per design: its targets
            plain = designs[:, : len(self.spec.parameters)].to(torch.float64)
            return self._built.stand_targets(plain).to(designs.dtype)
        return self._built.kinematics.default_foot_positions(designs).to(designs.dtype)

    def leg_inverse_kinematics(self, designs: torch.Tensor, foot_pos: torch.Tensor) -> torch.Tensor:
        """[n, J] the generic numeric IK (`kinematics.LegKinematics.inverse`)."""
        return self._built.kinematics.inverse(designs, foot_pos).to(designs.dtype)

    @classmethod
    def write_from_model(
        cls, name: str, source: str, into: str | None, package_path: list[str] | None = None
    ) -> dict:
        """`coadapt robot new`: a starting spec for the model file `source`, written as
        `<into>/<name>/` (default: the first folder of the robot path) with a copy of every
        file the model needs; `package_path`: folders holding the ROS packages a URDF's
        `package://` URIs name. {"folder", "notes" (lines for the user to check), "copied"
        (the files copied, inside the folder), "hint" (a line, or "")}. Bad input is a
        `UserError` and leaves nothing behind."""
        from coadapt_plugins.robots.specs.discovery import ENV_ROBOT_PATH, search_path
        from coadapt_plugins.robots.specs.new import write_robot

        target = Path(into) if into is not None else search_path()[0]
        packages = tuple(Path(p) for p in package_path or ())
        folder, notes, copied = write_robot(name, Path(source), target, packages)
        on_path = any(folder.parent.resolve() == p.resolve() for p in search_path())
        hint = "" if on_path else f"export {ENV_ROBOT_PATH}={folder.parent} to use it"
        return {"folder": str(folder), "notes": notes, "copied": copied, "hint": hint}

    def describe_rules(self) -> dict[str, str]:
        """How each parameter scales mass and inertia (`coadapt robot show`)."""
        from coadapt_plugins.robots.specs.build import mass_rule_text

        return {p.name: mass_rule_text(p) for p in self.spec.parameters}


def spec_robot_class(path: str | Path, *, description: str | None = None) -> type[SpecRobot]:
    """A `Robot` subclass for the spec at `path` (a robot.yaml or its folder), named by the
    spec. The file is read here, so a bad spec fails at registration with its field named."""
    from coadapt_plugins.robots.specs.spec import read_spec

    spec = read_spec(path)
    return type(
        f"SpecRobot_{spec.name.replace('-', '_')}",
        (SpecRobot,),
        {
            "name": spec.name,
            "spec_path": spec.folder,
            **_facts(spec, description),
            "__module__": __name__,
        },
    )


def _facts(spec: RobotSpec, description: str | None = None) -> dict[str, str]:
    """The class attributes read from a spec's files: its description, and the SHA-256 (12
    hex) of the spec, its model file and the files the model names (`plugin_version`)."""
    text = description or spec.description or f"robot from the spec {spec.folder / 'robot.yaml'}"
    digest = hashlib.sha256((spec.folder / "robot.yaml").read_bytes())
    if spec.model_path.is_file():
        digest.update(spec.model_path.read_bytes())
        for path in _needed_files(spec):
            digest.update(path.read_bytes())
    return {"description": text, "plugin_version": digest.hexdigest()[:12]}


class _ReadOnUse:
    """A class attribute of a `folder_robot_class` robot (its description, its version): the
    robot's files are read when one of them is first asked for, and both are set on the
    class. A spec that does not read, or names another robot than its folder, is the
    `UserError` of its field."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.attr = name

    def __get__(self, instance: object, owner: type[SpecRobot]) -> str:
        from coadapt_plugins.robots.specs.spec import read_spec

        from coadapt_core.errors import UserError

        spec = read_spec(owner.spec_path)
        if spec.name != owner.name:
            raise UserError(
                f"robot spec '{owner.spec_path / 'robot.yaml'}' names the robot '{spec.name}'; "
                f"the robots of this folder are named by their folders: '{owner.name}'",
                field="name",
            )
        facts = _facts(spec)
        for key, value in facts.items():
            setattr(owner, key, value)  # in place of these descriptors: read once
        return facts[self.attr]


def folder_robot_class(folder: str | Path) -> type[SpecRobot]:
    """A `Robot` subclass for the spec in `folder`, named by the folder; nothing is read until
    the robot is used (`_ReadOnUse`: its description and version, `SpecRobot.spec`)."""
    folder = Path(folder).resolve()
    return type(
        f"SpecRobot_{folder.name.replace('-', '_')}",
        (SpecRobot,),
        {
            "name": folder.name,
            "spec_path": folder,
            "description": _ReadOnUse(),
            "plugin_version": _ReadOnUse(),
            "__module__": __name__,
        },
    )


def _needed_files(spec: RobotSpec) -> list[Path]:
    """The files the spec's model names (includes, meshes, textures...) that are there, by
    reference: part of the robot's version, so a Ray node with other meshes is refused."""
    from coadapt_plugins.robots.specs.files import model_files

    from coadapt_core.errors import UserError

    try:
        files = model_files(spec.model_path, assets=spec.asset_paths)
    except UserError:  # the model says what is wrong with it when it loads
        return []
    return [f.path for f in sorted(files, key=lambda f: f.reference) if f.path.is_file()]
