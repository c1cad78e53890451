"""Resetting rows of the MuJoCo batch: the randomized parameters (Table 2 and the engine
robustness draws) written into the expanded model fields, the spawn pose above the ground,
a clean delay line and a restarted clock. `RowResetMixin` is that part of
`MujocoSimulator`; the restitution calibration it uses lives here too. MuJoCo and torch
are imported when a row is reset, not with the module (docs/architecture.md, "Start-up")."""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

from coadapt_core.physics.randomization import RandomizationConfig
from coadapt_core.physics.simulator import spawn_base_height

if TYPE_CHECKING:  # numpy is imported where it is used: listing the plugins loads none
    import numpy as np

#: each environment's MuJoCo clock restarts here at reset, so that MuJoCo resetting a
#: simulation itself on a bad state (clock back to 0) is always visible
RESET_CLOCK = 1.0


@functools.cache
def bad_state_warnings() -> list[int]:
    """MuJoCo's warnings for a bad state, after which it resets the simulation itself."""
    import mujoco

    warning = mujoco.mjtWarning
    return [int(warning.mjWARN_BADQPOS), int(warning.mjWARN_BADQVEL), int(warning.mjWARN_BADQACC)]


#: restitution calibration: a 40 kg box dropped at 1 m/s onto the plane (dt 5 ms, MuJoCo's
#: default solref time constant 0.02 s and solimp) rebounds with speed ratio RESTITUTION_MEASURED
#: at contact damping ratio RESTITUTION_DAMPRATIO (docs/simulators.md). Below 0.5 a resting
#: contact rings in a sustained 50 Hz limit cycle; above 1 MuJoCo softens the contact
#: (its stiffness scales with 1 / dampratio^2). So the reachable bounce is [0.14, 0.33].
RESTITUTION_DAMPRATIO = (1.0, 0.8, 0.6, 0.5)
RESTITUTION_MEASURED = (0.139, 0.191, 0.276, 0.328)


def restitution_to_dampratio(restitution: np.ndarray) -> np.ndarray:
    """Contact damping ratio (solref[1]) whose measured bounce is `restitution`, clamped to
    the reachable [0.14, 0.33]: 0 (and anything up to 0.14) is MuJoCo's default 1.0."""
    import numpy as np

    e = np.asarray(restitution, dtype=float)
    return np.interp(e, RESTITUTION_MEASURED, RESTITUTION_DAMPRATIO)


class RowResetMixin:
    """The reset side of `MujocoSimulator` (its batch, bound arrays and per-row facts)."""

    def _reset_rows(self, ids: np.ndarray, draw: bool = True) -> None:
        """New parameters, spawn pose and clean delay line for batch rows `ids` (in the
        order of the environments asked for); others untouched.
        `draw=False` (construction) keeps the parameters in force and spawns at the origin,
        consuming no randomness: the first `reset()` makes the first draw, as in every
        backend, so one seed gives one set of parameters everywhere."""
        import numpy as np

        if ids.size == 0:
            return
        import mujoco
        import torch

        b = self._live()
        envs = self._env_of_row[ids]
        params = self.draw_env_params(envs) if draw else self._params.take(envs)
        rows = torch.from_numpy(ids)
        self._pd_factor[rows] = params.pd_factor.cpu()
        self._motor_strength[rows] = params.motor_strength.cpu()
        delay_steps = params.delay_steps(self.physics_dt).clamp(max=self._delay.capacity - 1)
        params = params.numpy()
        # Table 2 parameters living in the model: sliding friction of every geom (MuJoCo
        # combines a contact's two geoms by max, so robot and terrain both carry it),
        # restitution as contact damping, base CoM shift
        friction = self._geom_friction[ids].copy()
        friction[..., 0] = params["friction"][:, None]
        self._expanded["geom_friction"][ids] = friction
        solref = self._geom_solref[ids].copy()
        solref[..., 1] = restitution_to_dampratio(params["restitution"])[:, None]
        # engine robustness (RandomizationConfig.contact_timeconst, joint_damping, armature):
        # contact softness, extra damping and armature of the robot's joints; a contact time
        # constant left at its nominal point keeps the model's own
        if self._timeconst_randomized():
            solref[..., 0] = params["contact_timeconst"][:, None]
        self._expanded["geom_solref"][ids] = solref
        dofs = self._dq_index
        damping = self._dof_damping[ids].copy()
        damping[:, dofs] += params["joint_damping"][:, None]
        self._expanded["dof_damping"][ids] = damping
        armature = self._dof_armature[ids].copy()
        armature[:, dofs] *= params["armature"][:, None]
        self._expanded["dof_armature"][ids] = armature
        base = self._ref.base_body_id
        ipos = self._expanded["body_ipos"]
        ipos[ids, base] = self._base_ipos[ids] + params["com_shift"]

        # spawn: standing height above the highest ground under either foot
        xy = self.draw_spawn_xy(envs) if draw else np.zeros((ids.size, 2))
        z = spawn_base_height(
            self.terrain_model,
            xy,
            self._foot_xy[ids],
            self._foot_radius[ids],
            self._standing_height[ids],
            fixed_base=self.fixed_base,
        )
        if self.fixed_base:
            body_pos = self._expanded["body_pos"]
            body_pos[ids, base] = np.column_stack([xy, z])
        batch_ids = np.unique(ids)  # mujoco.batch takes sorted, unique ids
        b.set_const(batch_ids)
        b.reset(batch_ids, stage=mujoco.mjtStage.mjSTAGE_NONE)
        if not self.fixed_base:
            self._qpos[ids, 0:2] = xy
            self._qpos[ids, 2] = z
            self._qpos[ids, 3:7] = (1.0, 0.0, 0.0, 0.0)
        q = self._qpos[ids]
        q[:, self._q_index] = self._default_q[ids]
        self._qpos[ids] = q
        self._qvel[ids] = 0.0
        self._ctrl[ids] = 0.0
        self._time[ids] = RESET_CLOCK
        b.forward(batch_ids, stage=mujoco.mjtStage.mjSTAGE_ACC)
        self._delay.reset(ids, torch.from_numpy(self._default_q[ids]))
        self._delay.set_delay(ids, delay_steps)
        self._expected_time[ids] = RESET_CLOCK
        self._warnings_seen[ids] = self._warnings[ids][:, bad_state_warnings(), 1]
        self._torque[ids] = 0.0

    def _timeconst_randomized(self) -> bool:
        lo, hi = self.randomization.contact_timeconst
        nominal = RandomizationConfig.NOMINAL["contact_timeconst"]
        return self.randomization.enabled and not (lo == hi == nominal)
