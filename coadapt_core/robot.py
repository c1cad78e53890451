"""The `Robot` plugin kind: a parametric robot whose model depends on a design vector.

A robot plugin owns its design space, turns a design into model descriptions, one per
format it can write (`RobotModel.formats`: "mjcf" for MuJoCo, "urdf" for Pinocchio and
PyBullet, any other name a simulator plugin reads), plus the actuator facts a simulator
needs, knows its leg kinematics (for the Raibert foot-placement reward), declares its legs
(order and gait phase offsets), validates designs and may ship trained universal policies.

The MJCF contract (checked by `coadapt_core.testing.RobotConformance`): the floating base is
the first joint, then the actuated joints; exactly one actuator per actuated joint (a
`<motor>` whose `joint` is that joint); one body per foot named in `foot_bodies`, in leg
order; collision geoms that touch the ground have `conaffinity="0"` and `contype="1"` (the
terrain's geoms have conaffinity 1, so robots do not self-collide); `total_mass` equals the
model's mass.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

from coadapt_core.design_space import DesignSpace

if TYPE_CHECKING:
    import numpy as np
    import torch


def _no_points() -> np.ndarray:
    """[0, 3]: no contact points given."""
    import numpy as np

    return np.zeros((0, 3))


def carried_files(formats: Mapping[str, str], fmt: str) -> dict[str, str]:
    """File name -> text of the "FMT:FILE" entries of a model's `formats`."""
    return {k.split(":", 1)[1]: v for k, v in formats.items() if k.startswith(f"{fmt}:")}


@dataclass
class RobotModel:
    """Everything a simulator and the locomotion task need about one design.

    Arrays over actuated joints are ordered as `joint_names`. Angles in rad, speeds in
    rad/s, torques in N m, lengths in m, masses in kg.
    """

    design: np.ndarray  # [design_dim]
    # model descriptions by format name: whatever formats the robot writes, e.g. "mjcf" (MuJoCo
    # XML; its floating base is the first joint, then the actuated joints in order) and "urdf"
    # (a floating base implied, root link = base; same frames as the MJCF). A simulator reads
    # the formats it declares (`Simulator.model_formats`) through `text(format)`; a new format
    # needs no change here. A key "FORMAT:FILE" holds a file FORMAT's text names by that file
    # name (a URDF's collision mesh), to be written beside it
    formats: Mapping[str, str]
    base_body: str  # name of the floating base body / root link
    joint_names: list[str]  # actuated joints, the order of every [num_joints] array below
    foot_bodies: list[str]  # one per leg, in the order of `Robot.legs()` (and of the IK's legs)
    default_joint_pos: np.ndarray  # [num_joints] standing pose
    kp: np.ndarray  # [num_joints] PD stiffness, N m / rad
    kd: np.ndarray  # [num_joints] PD damping, N m s / rad
    torque_limit: np.ndarray  # [num_joints] peak joint torque, N m
    speed_limit: np.ndarray  # [num_joints] no-load joint speed, rad/s
    joint_lower: np.ndarray  # [num_joints] position limits, rad
    joint_upper: np.ndarray  # [num_joints]
    standing_base_height: float  # base origin height above flat ground at the default pose
    total_mass: float
    foot_contact_points: np.ndarray = field(default_factory=_no_points)  # [k, 3] in the foot frame
    # lengths, segment masses, motor types, ...; an optional "units" entry maps keys to units
    # ({"thigh_length": "m"}), which `coadapt robot show` prints next to the values
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def num_joints(self) -> int:
        return len(self.joint_names)

    def text(self, fmt: str) -> str:
        """The model description in format `fmt`; a one-line `UserError` naming the formats
        the robot writes when it writes no such one."""
        value = self.formats.get(fmt)
        if not isinstance(value, str) or not value:
            from coadapt_core.errors import UserError

            given = ", ".join(sorted(k for k in self.formats if ":" not in k)) or "none"
            raise UserError(
                f"the robot model has no '{fmt}' description (it writes: {given}); "
                "a simulator that reads it needs a robot plugin that writes it",
                field="robot",
            )
        return value

    def files(self, fmt: str) -> dict[str, str]:
        """File name -> text of the files the `fmt` description names and carries with it
        (its "FMT:FILE" formats, e.g. a URDF's mesh stretched for this design)."""
        return carried_files(self.formats, fmt)


@dataclass(frozen=True)
class Leg:
    """One leg, as the gait clock and the metrics see it.

    Leg l's gait phase is (clock + phase_offset) mod 1; it is in stance for phase in
    [0, 0.5) and swings in [0.5, 1). A biped alternates with offsets (0, 0.5); a trotting
    quadruped moves diagonal pairs together, e.g. FL 0, FR 0.5, RL 0.5, RR 0."""

    name: str  # e.g. "left", "front_right"
    phase_offset: float  # in [0, 1)


@dataclass(frozen=True)
class Mirror:
    """The robot's left-right mirror image: the reflection through the base's x-z plane
    (base-frame y negated), which `TrainConfig.symmetry` trains the policy on as well.

    Joint k of the image is `joint_signs[k]` (+1 or -1) times joint `joints[k]` (positions
    relative to the standing pose, velocities and actions alike); leg l of the image is leg
    `legs[l]`; a design variable named in `designs` takes the value of the variable it names
    there (both directions listed), every other variable keeps its own."""

    joints: tuple[int, ...]
    joint_signs: tuple[float, ...]
    legs: tuple[int, ...]
    designs: Mapping[str, str] = field(default_factory=dict)


@dataclass
class Finding:
    """One named validation check and its outcome."""

    check: str  # e.g. "kinematics.thigh_length"
    ok: bool
    message: str  # one line: what was measured against what limit
    value: float | None = None
    limit: float | None = None


@dataclass
class ValidationReport:
    design: np.ndarray
    findings: list[Finding]

    @property
    def feasible(self) -> bool:
        return all(f.ok for f in self.findings)

    @property
    def reasons(self) -> list[str]:
        """One line per violated check."""
        return [f"{f.check}: {f.message}" for f in self.findings if not f.ok]

    def to_dict(self) -> dict:
        """Plain JSON values only (numpy bools and floats a check produced are converted)."""

        def num(x: Any) -> float | None:
            return None if x is None else float(x)

        return {
            "design": [float(x) for x in self.design],
            "feasible": bool(self.feasible),
            "findings": [
                {
                    "check": str(f.check),
                    "ok": bool(f.ok),
                    "message": str(f.message),
                    "value": num(f.value),
                    "limit": num(f.limit),
                }
                for f in self.findings
            ],
        }


class Robot(ABC):
    """A robot whose model is generated from a design vector."""

    #: user-facing key (`--robot kuafu`)
    name: ClassVar[str]
    #: rank as the default of its kind: with no name given, a command takes the installed
    #: plugin of highest rank (ties: the first name in alphabetical order; docs/plugins.md)
    default_rank: ClassVar[int] = 0
    #: one line for `coadapt plugins` and docs
    description: ClassVar[str] = ""

    @abstractmethod
    def design_space(self, mixed: bool = False) -> DesignSpace:
        """The design space; `mixed=True` adds discrete variables (e.g. motor types) if any."""

    @abstractmethod
    def nominal_design(self, mixed: bool = False) -> np.ndarray:
        """The reference design improvements are measured against."""

    @abstractmethod
    def build(self, design: np.ndarray) -> RobotModel:
        """Model descriptions and actuator facts for one design (validated against the
        design space of matching arity; raises `DesignError` when outside it)."""

    @abstractmethod
    def validate(self, design: np.ndarray) -> ValidationReport:
        """Named feasibility findings (kinematics, mass, statics, backend consistency)."""

    # -- leg kinematics, batched, for the gait reference of the locomotion task ----------
    @abstractmethod
    def leg_inverse_kinematics(self, designs: torch.Tensor, foot_pos: torch.Tensor) -> torch.Tensor:
        """Joint targets [n, num_joints] that put each foot at `foot_pos` [n, num_legs, 3],
        given relative to that leg's hip (the hip-pitch joint centre) in the base frame,
        for designs [n, design_dim]. Joints the IK does not decide keep the default pose."""

    @abstractmethod
    def default_foot_positions(self, designs: torch.Tensor) -> torch.Tensor:
        """[n, num_legs, 3] each foot (the point `leg_inverse_kinematics` places) relative to
        its hip at the default standing pose, base frame."""

    # -- legs and gait ------------------------------------------------------------------
    def legs(self) -> list[Leg]:
        """The legs in order: the order of `foot_bodies`, of the IK's `foot_pos` and of every
        [.., num_legs] array. Default: as many legs as `default_foot_positions` returns,
        named leg0, leg1, ..., with evenly spread phase offsets l / L (a biped alternates; a
        quadruped gets a four-beat walk, so a quadruped that should trot overrides this)."""
        import torch

        nominal = torch.as_tensor(self.nominal_design(False), dtype=torch.float64)[None]
        count = int(self.default_foot_positions(nominal).shape[1])
        return [Leg(f"leg{i}", i / count) for i in range(count)]

    def mirror(self) -> Mirror:
        """The robot's left-right mirror map (`Mirror`), or a one-line `UserError` saying why
        it has none. Default: none declared; a robot that is mirror-symmetric overrides
        this (the spec robots derive it from their legs' names and joint axes)."""
        from coadapt_core.errors import UserError

        raise UserError(
            f"robot '{self.name}' declares no left-right mirror map (Robot.mirror), which "
            "symmetry needs; train without it",
            field="symmetry",
        )

    # -- shipped policies ---------------------------------------------------------------
    def shipped_policy(self, terrain: str, mixed: bool = False) -> Path | None:
        """The universal policy checkpoint this robot ships for `terrain` and the continuous
        (`mixed=False`) or mixed design space, or None when it ships none.

        Default: the file `policies/<terrain>.pt` (`policies/<terrain>-mixed.pt` for the
        mixed space) in the folder of the module that defines the robot class, so a plugin
        ships a policy by putting a `coadapt train` checkpoint there and listing it as
        package data. Override to look elsewhere (a download cache, several versions)."""
        import inspect

        try:
            folder = Path(inspect.getfile(type(self))).parent
        except (TypeError, OSError):
            return None
        path = folder / "policies" / (f"{terrain}-mixed.pt" if mixed else f"{terrain}.pt")
        return path if path.is_file() else None

    def hip_height(self, designs: torch.Tensor) -> torch.Tensor:
        """[n] vertical hip-to-foot distance at the default standing pose."""
        return -self.default_foot_positions(designs)[..., 2].mean(dim=-1)

    def design_space_for(self, design: np.ndarray) -> DesignSpace:
        """The space (continuous or mixed) whose arity matches `design`."""
        import numpy as np

        design = np.atleast_1d(np.asarray(design, dtype=float))
        plain, mixed = self.design_space(False), self.design_space(True)
        if design.shape[0] == mixed.dim and mixed.dim != plain.dim:
            return mixed
        return plain


def joint_table(model: RobotModel) -> list[dict[str, Any]]:
    """A model's actuated joints in policy order, as plain data: default angle, limits, PD
    gains, motor torque and speed limits (`coadapt robot show`, the handoff's design sheet)."""
    import numpy as np

    return [
        {
            "name": name,
            "default": float(model.default_joint_pos[k]),
            "lower": float(model.joint_lower[k]),
            "upper": float(model.joint_upper[k]),
            "kp": float(model.kp[k]),
            "kd": float(model.kd[k]),
            "torque_limit": float(model.torque_limit[k]),
            "speed_limit": float(model.speed_limit[k]),
            "speed_limit_rpm": float(model.speed_limit[k] * 60.0 / (2.0 * np.pi)),
        }
        for k, name in enumerate(model.joint_names)
    ]
