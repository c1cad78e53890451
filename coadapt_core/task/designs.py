"""What the locomotion task derives from each environment's design, once per change of
designs rather than at every step: the default joint pose, the feet at the standing pose
(the Raibert reference starts from them), the total mass (for objectives such as the cost of
transport; one model build per distinct design) and, for the binding motor limit, each
joint's no-load speed. The design input xi the policy reads is `task.env.normalize_designs`
over the bounds (`low`, `high`) kept here."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import torch

if TYPE_CHECKING:
    from coadapt_core.physics.simulator import Simulator
    from coadapt_core.robot import Robot

#: distinct designs whose mass is kept before the cache starts again
MASS_CACHE_SIZE = 4096


class DesignInputs:
    """The per-environment design buffers of a `LocomotionEnv`, refreshed from its simulator
    (`refresh`) whenever designs change: `designs` [N, D], `default_joint_pos` [N, J],
    `default_feet` [N, L, 3] (relative to the hips, base frame) and `total_mass` [N] kg
    (NaN for a test robot without models)."""

    def __init__(self, robot: Robot, low: np.ndarray, high: np.ndarray, device: torch.device):
        self.robot = robot
        self.device = device
        self.low = torch.as_tensor(low, dtype=torch.float32, device=device)
        self.high = torch.as_tensor(high, dtype=torch.float32, device=device)
        self._mass: dict[tuple[float, ...], float] = {}
        self._nominal_leg: float | None = None
        #: also keep `speed_limit` [N, J], each joint's motor no-load speed, rad/s (for the
        #: binding limit)
        self.track_speed_limit = False
        self._speed: dict[tuple[float, ...], np.ndarray] = {}

    @property
    def nominal_leg_length(self) -> float:
        """The nominal design's hip height at the standing pose, m (of the space `low` spans)."""
        if self._nominal_leg is None:
            mixed = self.robot.design_space(True)
            nominal = self.robot.nominal_design(
                mixed.dim == len(self.low) and mixed.dim != self.robot.design_space().dim
            )
            with torch.no_grad():
                design = torch.as_tensor(
                    np.asarray(nominal, dtype=np.float32)[None], device=self.device
                )
                self._nominal_leg = float(self.robot.hip_height(design)[0])
        return self._nominal_leg

    def refresh(self, sim: Simulator) -> None:
        designs = np.asarray(sim.designs, dtype=np.float32)
        self.designs = torch.as_tensor(designs, device=self.device)  # [N, D]
        self.default_joint_pos = sim.default_joint_pos.to(self.device).float()  # [N, J]
        with torch.no_grad():
            self.default_feet = (
                self.robot.default_foot_positions(self.designs).to(self.device).float()
            )  # [N, L, 3]
        if len(self._mass) > MASS_CACHE_SIZE:
            self._mass.clear()
        self.total_mass = torch.tensor(
            [self._mass_of(row) for row in np.asarray(sim.designs, dtype=float)],
            dtype=torch.float32,
            device=self.device,
        )
        if self.track_speed_limit:
            rows = [self._speed_of(row) for row in np.asarray(sim.designs, dtype=float)]
            self.speed_limit = torch.as_tensor(
                np.stack(rows), dtype=torch.float32, device=self.device
            )  # [N, J]

    def _speed_of(self, design: np.ndarray) -> np.ndarray:
        key = tuple(design.tolist())
        if key not in self._speed:
            if len(self._speed) > MASS_CACHE_SIZE:
                self._speed.clear()
            self._speed[key] = np.asarray(self.robot.build(design).speed_limit, dtype=float)
        return self._speed[key]

    def _mass_of(self, design: np.ndarray) -> float:
        key = tuple(design.tolist())
        if key not in self._mass:
            try:
                self._mass[key] = float(self.robot.build(design).total_mass)
            except NotImplementedError:  # a test robot without models: mass unknown
                self._mass[key] = float("nan")
        return self._mass[key]
