"""The state of the MuJoCo batch as a `SimState` in environment order: base pose and
velocities from the free joint, joint state, the last policy step's torque, foot positions
(moved to the current state to first order) and foot contacts from the contact sensors.
`StateReadMixin` is that part of `MujocoSimulator`; `as_slice` and `ancestor_dofs` index the
batch's arrays."""

from __future__ import annotations

from typing import TYPE_CHECKING

from coadapt_plugins.simulators.mujoco.compose import CONTACT_SENSOR_DIM

from coadapt_core.physics.simulator import SimState, quat_rotate

if TYPE_CHECKING:
    import mujoco
    import numpy as np
    import torch


class StateReadMixin:
    """The state side of `MujocoSimulator` (its bound arrays, rows and reference model)."""

    def _build_state(self) -> SimState:
        import numpy as np
        import torch

        n = self._n
        order = self._row  # row-order arrays below are gathered into environment order
        qpos, qvel = self._qpos[order], self._qvel[order]
        if self.fixed_base:
            base_pos = self._xpos[order, self._ref.base_body_id]
            base_quat = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
            lin_vel = np.zeros((n, 3))
            ang_vel = np.zeros((n, 3))
        else:
            base_pos = qpos[:, 0:3]
            base_quat = qpos[:, 3:7]
            lin_vel = qvel[:, 0:3]  # free joint: linear velocity in the world frame
            ang_vel = quat_rotate(base_quat, qvel[:, 3:6])  # free joint: angular in the body frame
        sd = self._sensordata[order]
        found = np.stack([sd[:, a] for a in self._sensor_adr], axis=1)  # [N, L] number of contacts
        force = np.stack(
            [sd[:, a + 1 : a + CONTACT_SENSOR_DIM] for a in self._sensor_adr], axis=1
        )  # [N, L, 3]
        normal_force = np.abs(force @ self._normal)  # [N, L]
        terrain_h = self.terrain_model.height_at(base_pos[:, :2])  # [N]

        def f32(x: np.ndarray) -> torch.Tensor:
            return torch.from_numpy(np.ascontiguousarray(x, dtype=np.float32))

        state = SimState(
            base_pos=f32(base_pos),
            base_quat=f32(base_quat),
            base_lin_vel=f32(lin_vel),
            base_ang_vel=f32(ang_vel),
            joint_pos=f32(qpos[:, self._q_index]),
            joint_vel=f32(qvel[:, self._dq_index]),
            joint_torque=f32(self._torque[order]),
            foot_pos=f32(self._foot_positions()[order]),
            foot_contact=torch.from_numpy(found > 0),
            foot_contact_force=f32(normal_force),
            terrain_height=f32(terrain_h),
            diverged=torch.from_numpy(self._diverged[order]),
        )
        if str(self.device) != "cpu":
            state = state.to(self.device)
        return state

    def _foot_positions(self) -> np.ndarray:
        """[N, L, 3] foot body origins at the current state.

        Derived fields (xpos, cdof) describe the state before the last physics step, as
        with mj_step. Recomputing the position stage would cost half a physics step (it
        includes collision detection). Instead each origin moves by dt times its velocity
        under the new joint velocities (MuJoCo's Euler step moves positions with the new
        velocities), which is exact to first order, impacts included (tests check < 2 mm).
        """
        import numpy as np

        qvel = self._qvel
        out = np.empty((self._n, len(self._foot_dofs), 3))
        for leg, (body, dofs) in enumerate(
            zip(self._ref.foot_body_ids, self._foot_dofs, strict=True)
        ):
            twist = np.einsum("nds,nd->ns", self._cdof[:, dofs], qvel[:, dofs])  # [N, 6]
            pos = self._xpos[:, body]  # [N, 3]
            lever = pos - self._subtree_com[:, self._foot_root[leg]]
            out[:, leg] = pos + self.physics_dt * (twist[:, 3:] + np.cross(twist[:, :3], lever))
        return out


def as_slice(index: np.ndarray) -> slice | np.ndarray:
    """`index` as a slice when its entries are consecutive (a view, not a copy, of the rows'
    columns), else as an integer array."""
    import numpy as np

    index = np.asarray(index, dtype=int)
    if index.size and np.array_equal(index, np.arange(index[0], index[0] + index.size)):
        return slice(int(index[0]), int(index[0] + index.size))
    return index


def ancestor_dofs(model: mujoco.MjModel, body: int) -> np.ndarray:
    """Degrees of freedom that move `body` (its own and its ancestors')."""
    import numpy as np

    dofs = []
    while body > 0:
        start, count = model.body_dofadr[body], model.body_dofnum[body]
        dofs.extend(range(start, start + count))
        body = model.body_parentid[body]
    return np.array(sorted(dofs), dtype=int)
