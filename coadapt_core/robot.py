"""The `Robot` plugin kind: a parametric robot whose model depends on a design vector.

A robot plugin owns its design space, turns a design into model descriptions (MJCF for
MuJoCo, URDF for Pinocchio and PyBullet) plus the actuator facts a simulator needs, knows its
leg kinematics (for the Raibert foot-placement reward) and validates designs.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from coadapt_core.design_space import DesignSpace

if TYPE_CHECKING:
    import torch


@dataclass
class RobotModel:
    """Everything a simulator and the locomotion task need about one design.

    Arrays over actuated joints are ordered as `joint_names`. Angles in rad, speeds in
    rad/s, torques in N m, lengths in m, masses in kg.
    """

    design: np.ndarray  # [design_dim]
    mjcf: str  # MuJoCo XML; its floating base is the first joint, then the actuated joints in order
    urdf: str  # URDF with a floating base implied (root link = base); same frames as the MJCF
    base_body: str  # name of the floating base body / root link
    joint_names: list[str]  # actuated joints, the order of every [num_joints] array below
    foot_bodies: list[str]  # one per leg, in leg order (left, right)
    default_joint_pos: np.ndarray  # [num_joints] standing pose
    kp: np.ndarray  # [num_joints] PD stiffness, N m / rad
    kd: np.ndarray  # [num_joints] PD damping, N m s / rad
    torque_limit: np.ndarray  # [num_joints] peak joint torque, N m
    speed_limit: np.ndarray  # [num_joints] no-load joint speed, rad/s
    joint_lower: np.ndarray  # [num_joints] position limits, rad
    joint_upper: np.ndarray  # [num_joints]
    standing_base_height: float  # base origin height above flat ground at the default pose
    total_mass: float
    foot_contact_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # [k, 3] in the foot frame
    info: dict[str, Any] = field(default_factory=dict)  # lengths, segment masses, motor types, ...

    @property
    def num_joints(self) -> int:
        return len(self.joint_names)


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
        return {
            "design": [float(x) for x in self.design],
            "feasible": self.feasible,
            "findings": [
                {"check": f.check, "ok": f.ok, "message": f.message, "value": f.value, "limit": f.limit}
                for f in self.findings
            ],
        }


class Robot(ABC):
    """A robot whose model is generated from a design vector."""

    #: user-facing key (`--robot kuafu`)
    name: ClassVar[str]
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

    def hip_height(self, designs: torch.Tensor) -> torch.Tensor:
        """[n] vertical hip-to-foot distance at the default standing pose."""
        return -self.default_foot_positions(designs)[..., 2].mean(dim=-1)

    def design_space_for(self, design: np.ndarray) -> DesignSpace:
        """The space (continuous or mixed) whose arity matches `design`."""
        design = np.atleast_1d(np.asarray(design, dtype=float))
        plain, mixed = self.design_space(False), self.design_space(True)
        if design.shape[0] == mixed.dim and mixed.dim != plain.dim:
            return mixed
        return plain
