"""`Kuafu`: the Robot plugin. Design spaces, cached model building and batched leg
kinematics; validation lives in `validation.py` (Pinocchio, imported when used)."""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

from coadapt_plugins.robots.kuafu import constants as C

from coadapt_core.design_space import Continuous, DesignSpace, Discrete
from coadapt_core.errors import DesignError
from coadapt_core.robot import Robot, RobotModel, ValidationReport

if TYPE_CHECKING:
    import numpy as np
    import torch

#: designs closer than this are the same model (cache key rounding)
DESIGN_DECIMALS = 6

_CONTINUOUS = (
    Continuous("thigh_scale", *C.SCALE_BOUNDS, unit="x 0.35 m"),
    Continuous("shank_scale", *C.SCALE_BOUNDS, unit="x 0.35 m"),
)
_MOTORS = tuple(float(k) for k in sorted(C.MOTOR_TYPES))
_DISCRETE = (
    Discrete("hip_motor", _MOTORS, unit="Table 8 type"),
    Discrete("knee_motor", _MOTORS, unit="Table 8 type"),
)


class Kuafu(Robot):
    """The Kuafu humanoid: thigh and shank scale (and hip/knee motor types when mixed)."""

    name: ClassVar[str] = "kuafu"
    default_rank: ClassVar[int] = 10  # the default --robot
    description: ClassVar[str] = (
        "Kuafu humanoid (42 kg, 1.6 m): thigh/shank scale in [0.5, 1.5], hip/knee motor types 1-3"
    )

    def design_space(self, mixed: bool = False) -> DesignSpace:
        return DesignSpace(_CONTINUOUS + _DISCRETE if mixed else _CONTINUOUS)

    def nominal_design(self, mixed: bool = False) -> np.ndarray:
        import numpy as np

        nominal = [1.0, 1.0] + ([float(C.NOMINAL_MOTOR_TYPE)] * 2 if mixed else [])
        return np.array(nominal)

    def check_design(self, design: np.ndarray) -> np.ndarray:
        """The design as a validated float vector; `DesignError` naming the variable and
        what is accepted otherwise. 2 values: (thigh_scale, shank_scale) with motor types
        (1, 1); 4 values: (thigh_scale, shank_scale, hip_motor, knee_motor)."""
        import numpy as np

        values = np.atleast_1d(np.asarray(design, dtype=float))
        if values.ndim != 1 or values.shape[0] not in (2, 4):
            raise DesignError(
                f"kuafu design needs 2 values (thigh_scale, shank_scale) or 4 values "
                f"(thigh_scale, shank_scale, hip_motor, knee_motor), got {values.size}",
                field="design",
            )
        return self.design_space(values.shape[0] == 4).validate(values)

    def build(self, design: np.ndarray) -> RobotModel:
        import numpy as np
        from coadapt_plugins.robots.kuafu.generator import build_cached

        values = self.check_design(design)
        if values.shape[0] == 4:
            values[2:] = np.round(values[2:])
        return build_cached(tuple(float(x) for x in np.round(values, DESIGN_DECIMALS)))

    def validate(self, design: np.ndarray) -> ValidationReport:
        from coadapt_plugins.robots.kuafu.validation import validate_model

        return validate_model(self.build(design))

    # -- leg kinematics (batched torch) -----------------------------------------------------
    @staticmethod
    def _lengths(designs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """([n, 1], [n, 1]) thigh and shank lengths of the models `build` makes (whose
        designs are rounded to DESIGN_DECIMALS)."""
        import torch

        scale = 10.0**DESIGN_DECIMALS
        rounded = torch.round(designs[:, :2] * scale) / scale  # [n, 2]
        return C.NOMINAL_LINK_LENGTH * rounded[:, 0:1], C.NOMINAL_LINK_LENGTH * rounded[:, 1:2]

    def default_foot_positions(self, designs: torch.Tensor) -> torch.Tensor:
        """[n, 2, 3] ankle joint centre relative to the hip joint centre (where the hip roll
        and hip pitch axes meet) at the default pose, base frame: straight below the hip at
        0.94 of the full leg length."""
        import torch

        l0, l1 = self._lengths(designs)  # [n, 1]
        depth = C.STANCE_EXTENSION * (l0 + l1)  # [n, 1]
        feet = torch.zeros(designs.shape[0], 2, 3, dtype=designs.dtype, device=designs.device)
        feet[:, :, 2] = -depth
        return feet

    def leg_inverse_kinematics(self, designs: torch.Tensor, foot_pos: torch.Tensor) -> torch.Tensor:
        """[n, 8] joint targets putting each ankle joint centre at foot_pos [n, 2, 3]
        (relative to its hip joint centre, base frame). Hip roll turns the leg plane towards
        the foot's lateral offset; a 2-link IK in that plane gives hip pitch and knee (knee
        bent forward, knee >= 0); the ankle keeps the sole's pitch parallel to the ground.
        Unreachable targets are clamped to the reachable annulus."""
        import torch

        l0, l1 = self._lengths(designs)  # [n, 1]
        x, y, z = foot_pos[..., 0], foot_pos[..., 1], foot_pos[..., 2]  # [n, 2]
        roll = torch.atan2(y, -z)  # [n, 2]; rotation about +x moving the foot to +y
        depth = torch.sqrt(y * y + z * z)  # [n, 2] hip-to-ankle distance in the rolled leg plane
        reach = torch.sqrt(x * x + depth * depth)
        reach = torch.minimum(torch.maximum(reach, (l0 - l1).abs() + 1e-9), (l0 + l1) * (1 - 1e-9))
        cos_knee = (reach * reach - l0 * l0 - l1 * l1) / (2.0 * l0 * l1)
        knee = torch.acos(cos_knee.clamp(-1.0, 1.0))  # [n, 2]
        pitch = torch.atan2(-x, depth) - torch.atan2(
            l1 * torch.sin(knee), l0 + l1 * torch.cos(knee)
        )
        ankle = -(pitch + knee)
        q = torch.stack([roll, pitch, knee, ankle], dim=-1)  # [n, 2, 4] (leg, joint)
        return q.reshape(designs.shape[0], 8)
