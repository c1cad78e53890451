"""`Qilin`: the Robot plugin. Design spaces, cached model building and batched leg
kinematics; validation lives in `validation.py` (Pinocchio, imported when used)."""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

from coadapt_plugins.robots.qilin import constants as C

from coadapt_core.design_space import Continuous, DesignSpace, Discrete
from coadapt_core.errors import DesignError
from coadapt_core.robot import Leg, Mirror, Robot, RobotModel, ValidationReport

if TYPE_CHECKING:
    import numpy as np
    import torch

#: designs closer than this are the same model (cache key rounding)
DESIGN_DECIMALS = 6

_CONTINUOUS = (
    Continuous("thigh_scale", *C.SCALE_BOUNDS, unit=f"x {C.NOMINAL_THIGH} m"),
    Continuous("calf_scale", *C.SCALE_BOUNDS, unit=f"x {C.NOMINAL_CALF} m"),
)
_MOTORS = tuple(float(k) for k in sorted(C.MOTOR_TYPES))
_DISCRETE = (
    Discrete("hip_motor", _MOTORS, unit="type"),
    Discrete("knee_motor", _MOTORS, unit="type"),
)


class Qilin(Robot):
    """A 12-joint trotting quadruped modelled on the Unitree Go1: thigh and calf scale (and
    hip/knee motor types when mixed)."""

    name: ClassVar[str] = "qilin"
    description: ClassVar[str] = (
        "quadruped modelled on the Unitree Go1 (12.7 kg, 12 joints): thigh/calf scale in "
        "[0.7, 1.3], hip/knee motor types 1-2"
    )

    def design_space(self, mixed: bool = False) -> DesignSpace:
        return DesignSpace(_CONTINUOUS + _DISCRETE if mixed else _CONTINUOUS)

    def nominal_design(self, mixed: bool = False) -> np.ndarray:
        import numpy as np

        motors = [float(C.NOMINAL_HIP_MOTOR), float(C.NOMINAL_KNEE_MOTOR)] if mixed else []
        return np.array([1.0, 1.0, *motors])

    def legs(self) -> list[Leg]:
        return [Leg(leg, C.TROT[leg]) for leg in C.LEGS]

    def mirror(self) -> Mirror:
        """Left and right trade places (FL <-> FR, RL <-> RR, the trot's pairs swapped: the
        clock moves half a period); the abduction joints (x axis on every leg) change sign,
        hip and knee (y axis) keep it; every design variable applies to all legs alike.
        `tests/core/test_symmetry.py` checks it against the model in MuJoCo."""
        side = {"FL": "FR", "FR": "FL", "RL": "RR", "RR": "RL"}
        legs = tuple(C.LEGS.index(side[leg]) for leg in C.LEGS)
        n = len(C.JOINTS)
        joints = tuple(legs[k // n] * n + k % n for k in range(len(C.JOINT_NAMES)))
        signs = tuple(-1.0 if j == "abduction" else 1.0 for _ in C.LEGS for j in C.JOINTS)
        return Mirror(joints, signs, legs)

    def check_design(self, design: np.ndarray) -> np.ndarray:
        """The design as a validated float vector; `DesignError` naming what is accepted."""
        import numpy as np

        values = np.atleast_1d(np.asarray(design, dtype=float))
        if values.ndim != 1 or values.shape[0] not in (2, 4):
            raise DesignError(
                f"qilin design needs 2 values (thigh_scale, calf_scale) or 4 values (thigh_scale, "
                f"calf_scale, hip_motor, knee_motor), got {values.size}",
                field="design",
            )
        return self.design_space(values.shape[0] == 4).validate(values)

    def build(self, design: np.ndarray) -> RobotModel:
        import numpy as np
        from coadapt_plugins.robots.qilin.generator import build_cached

        values = self.check_design(design)
        if values.shape[0] == 4:
            values[2:] = np.round(values[2:])
        return build_cached(tuple(float(x) for x in np.round(values, DESIGN_DECIMALS)))

    def validate(self, design: np.ndarray) -> ValidationReport:
        from coadapt_plugins.robots.qilin.validation import validate_model

        return validate_model(self.build(design))

    # -- leg kinematics (batched torch) -----------------------------------------------------
    @staticmethod
    def _lengths(designs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """([n, 1], [n, 1]) thigh and calf lengths of the models `build` makes."""
        import torch

        scale = 10.0**DESIGN_DECIMALS
        rounded = torch.round(designs[:, :2] * scale) / scale
        return C.NOMINAL_THIGH * rounded[:, 0:1], C.NOMINAL_CALF * rounded[:, 1:2]

    def default_foot_positions(self, designs: torch.Tensor) -> torch.Tensor:
        """[n, 4, 3] foot centre relative to its hip-pitch joint at the default pose: straight
        below it at the Go1 home pose's share of the leg length."""
        import torch

        thigh, calf = self._lengths(designs)
        feet = torch.zeros(
            designs.shape[0], len(C.LEGS), 3, dtype=designs.dtype, device=designs.device
        )
        feet[:, :, 2] = -C.STANCE_SHARE * (thigh + calf)
        return feet

    def leg_inverse_kinematics(self, designs: torch.Tensor, foot_pos: torch.Tensor) -> torch.Tensor:
        """[n, 12] joint targets putting each foot centre at foot_pos [n, 4, 3] (relative to
        its hip-pitch joint at abduction 0, base frame). The abduction turns the leg plane,
        which sits `THIGH_OFFSET` outboard of the abduction axis, through the foot; a two-link
        IK in that plane gives hip and knee (knee bent backwards). Unreachable targets are
        clamped to the reachable annulus."""
        import torch

        thigh, calf = self._lengths(designs)  # [n, 1]
        sides = torch.tensor(
            [C.side(leg) for leg in C.LEGS], dtype=designs.dtype, device=designs.device
        )
        offset = sides * C.THIGH_OFFSET  # [4] the hip-pitch joint's y from the abduction axis
        x = foot_pos[..., 0]
        y = foot_pos[..., 1] + offset  # [n, 4] relative to the abduction axis
        z = foot_pos[..., 2]
        # a point (d, -h) of the leg plane turned by the abduction a about x:
        # (d cos a + h sin a, d sin a - h cos a)
        depth = torch.sqrt((y * y + z * z - offset * offset).clamp(min=1e-12))  # [n, 4] h
        abduction = torch.atan2(z, y) - torch.atan2(-depth, offset)
        abduction = torch.remainder(abduction + torch.pi, 2 * torch.pi) - torch.pi
        reach = torch.sqrt(x * x + depth * depth)
        reach = torch.minimum(
            torch.maximum(reach, (thigh - calf).abs() + 1e-9), (thigh + calf) * (1 - 1e-9)
        )
        knee = -torch.acos(
            ((reach * reach - thigh * thigh - calf * calf) / (2 * thigh * calf)).clamp(-1.0, 1.0)
        )
        hip = torch.atan2(-x, depth) - torch.atan2(
            calf * torch.sin(knee), thigh + calf * torch.cos(knee)
        )
        return torch.stack([abduction, hip, knee], dim=-1).reshape(
            designs.shape[0], 3 * len(C.LEGS)
        )
