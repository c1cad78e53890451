"""The binding motor speed limit (`task.motor_speed_limit: binding`, issue 41): no torque at all
beyond a joint's no-load speed, in MuJoCo and PyBullet alike, and the task ends an episode whose
joint stays beyond it; the default ("soft") keeps the torque-speed envelope's braking torque."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from coadapt_core.errors import UserError
from coadapt_core.physics.actuation import bind_speed, pd_torque
from coadapt_core.physics.randomization import RandomizationConfig


def test_bind_speed_zeroes_exactly_the_joints_beyond_their_no_load_speed():
    dq_max = torch.tensor([[10.0, 10.0, 20.0, 20.0]])
    dq = torch.tensor([[9.9, -10.5, 25.0, -5.0]])
    tau = pd_torque(
        torch.zeros(1, 4),
        torch.full((1, 4), 0.5),
        dq,
        torch.full((1, 4), 100.0),
        torch.full((1, 4), 1.0),
        torch.full((1, 4), 40.0),
        dq_max,
    )
    # soft: PD -50 - dq, clipped by the envelope: braking at full torque (also beyond dq_max,
    # joint 2), no torque driving a joint further beyond it (joint 1), -40 x (1 - 5/20) (joint 3)
    assert tau.tolist()[0] == pytest.approx([-40.0, 0.0, -40.0, -30.0])
    bound = bind_speed(tau.clone(), dq, dq_max)
    assert bound.tolist()[0] == pytest.approx([-40.0, 0.0, 0.0, -30.0])  # binding: joint 2 too


def _overspeed_step(sim, set_velocity, dq_max: np.ndarray) -> np.ndarray:
    """One physics step (decimation 1) from joints moving at +1.5 x their no-load speed, the
    targets 1 rad behind them (the PD law brakes): the torques reported [N, J]."""
    sim.reset()
    set_velocity(1.5 * dq_max)
    return sim.step(sim.default_joint_pos - 1.0).joint_torque.double().cpu().numpy()


def _mujoco(robot, designs, mode):
    from coadapt_plugins.simulators.mujoco.simulator import MujocoSimulator

    sim = MujocoSimulator(
        robot, designs, decimation=1, fixed_base=True, randomization=RandomizationConfig.off()
    )
    sim.set_speed_limit(mode)

    def set_velocity(v):
        sim._qvel[:, sim._dq_index] = v

    return sim, set_velocity


def _pybullet(robot, designs, mode):
    pytest.importorskip("pybullet")
    import pybullet as p
    from coadapt_plugins.simulators.pybullet.simulator import PyBulletSimulator

    sim = PyBulletSimulator(
        robot,
        designs,
        processes=0,
        decimation=1,
        fixed_base=True,
        randomization=RandomizationConfig.off(),
    )
    sim.set_speed_limit(mode)
    eng = sim._engine

    def set_velocity(v):
        q, _ = eng._joints()
        for e in range(eng.k):
            for j, jid in enumerate(eng.joint_ids[e]):
                p.resetJointState(
                    eng.bodies[e],
                    jid,
                    float(q[e, j]),
                    float(v[e, j]),
                    physicsClientId=eng.clients[e],
                )

    return sim, set_velocity


@pytest.mark.slow
@pytest.mark.parametrize("make", [_mujoco, _pybullet], ids=["mujoco", "pybullet"])
def test_no_torque_beyond_no_load_speed_when_binding_braking_torque_when_soft(make):
    from coadapt_plugins.robots.kuafu.robot import Kuafu

    robot = Kuafu()
    designs = np.array([[1.0, 1.0], [0.6, 1.15]])
    models = [robot.build(d) for d in designs]
    dq_max = np.stack([m.speed_limit for m in models])
    tau_max = np.stack([m.torque_limit for m in models])
    torques = {}
    for mode in ("soft", "binding"):
        sim, set_velocity = make(robot, designs, mode)
        with sim:
            assert sim.speed_limit == mode
            torques[mode] = _overspeed_step(sim, set_velocity, dq_max)
    # soft: the envelope's lower bound at 1.5 x dq_max is -tau_max; kp x 1 rad exceeds it
    np.testing.assert_allclose(torques["soft"], -tau_max, rtol=1e-6)
    np.testing.assert_array_equal(torques["binding"], np.zeros_like(tau_max))


def test_a_backend_refuses_a_mode_it_does_not_declare():
    from coadapt_plugins.robots.kuafu.robot import Kuafu
    from coadapt_plugins.simulators.mujoco.simulator import MujocoSimulator

    class SoftMujoco(MujocoSimulator):
        speed_limit_modes = ("soft",)

    with SoftMujoco(
        Kuafu(), np.array([[1.0, 1.0]]), randomization=RandomizationConfig.off()
    ) as sim:
        with pytest.raises(UserError, match=r"motor_speed_limit.*offers soft, got 'binding'"):
            sim.set_speed_limit("binding")
        assert sim.speed_limit == "soft"


@pytest.mark.slow
def test_task_ends_an_episode_beyond_no_load_speed_for_overspeed_seconds_when_binding():
    from coadapt_plugins.robots.kuafu.robot import Kuafu
    from coadapt_plugins.simulators.mujoco.simulator import MujocoSimulator

    from coadapt_core.task.config import TaskConfig
    from coadapt_core.task.env import LocomotionEnv

    robot = Kuafu()
    designs = np.array([[1.0, 1.0], [1.0, 1.0]])
    dq_max = torch.tensor(np.array(robot.build(designs[0]).speed_limit), dtype=torch.float32)
    for mode in ("soft", "binding"):
        cfg = TaskConfig(motor_speed_limit=mode, overspeed_seconds=0.1)
        with MujocoSimulator(robot, designs, randomization=RandomizationConfig.off()) as sim:
            env = LocomotionEnv(sim, robot, cfg)
            assert sim.speed_limit == mode
            state = env.state
            gravity = state.base_frame()[2]
            fast = state.joint_vel.clone()
            fast[0, 2] = 1.2 * dq_max[2]  # env 0: one joint beyond its no-load speed; env 1 not
            over = dataclasses.replace(state, joint_vel=fast)
            ended = [env._termination(over, gravity)[1].tolist() for _ in range(6)]
            if mode == "soft":
                assert not any(any(e) for e in ended)
            else:  # 0.1 s = 5 policy steps of 0.02 s: the fifth ends env 0
                assert [e[0] for e in ended[:5]] == [False] * 4 + [True] and not any(
                    e[1] for e in ended
                )
                assert env.design_inputs.speed_limit[0].tolist() == pytest.approx(dq_max.tolist())
                env._termination(
                    state, gravity
                )  # a step back under the limit: the count starts again
                assert env.overspeed_time[0].item() == 0.0


@pytest.mark.slow
@pytest.mark.parametrize("sim_name", ["mujoco", "pybullet"])
def test_nominal_gain_law_gives_every_design_the_nominal_designs_pd_gains(sim_name):
    """`task.gain_law: nominal` (Simulator.set_gain_law): the torque a joint receives is the
    shared PD law with the nominal design's kp and kd, whatever the design; "robot" keeps each
    design's own (Kuafu: knee kp 458 / 800 / 1 253 at thigh 0.5 / 1.0 / 1.5)."""
    from coadapt_plugins.robots.kuafu.robot import Kuafu

    if sim_name == "pybullet":
        pytest.importorskip("pybullet")
        from coadapt_plugins.simulators.pybullet.simulator import PyBulletSimulator as Sim

        extra = {"processes": 0}
    else:
        from coadapt_plugins.simulators.mujoco.simulator import MujocoSimulator as Sim

        extra = {}
    robot = Kuafu()
    designs = np.array([[0.5, 1.0], [1.5, 1.0]])
    own = [robot.build(d) for d in designs]
    nominal = robot.build(robot.nominal_design())
    assert [m.kp[2] for m in own] == pytest.approx([457.9, 1252.9], abs=0.5) and nominal.kp[
        2
    ] == pytest.approx(800.0)
    for law in ("robot", "nominal"):
        with Sim(
            robot,
            designs,
            decimation=1,
            fixed_base=True,
            randomization=RandomizationConfig.off(),
            **extra,
        ) as sim:
            sim.set_gain_law(law)
            assert sim.gain_law == law
            state = sim.reset()
            targets = sim.default_joint_pos.double().cpu() + 0.05
            after = sim.step(targets.to(sim.default_joint_pos))
            models = own if law == "robot" else [nominal, nominal]
            gains = [
                torch.tensor(np.stack([getattr(m, k) for m in models]), dtype=torch.float64)
                for k in ("kp", "kd", "torque_limit", "speed_limit")
            ]
            expected = pd_torque(
                targets, state.joint_pos.double().cpu(), state.joint_vel.double().cpu(), *gains
            )
            torch.testing.assert_close(
                after.joint_torque.double().cpu(), expected, rtol=1e-4, atol=2e-2
            )
            # the knee of the short-thigh design: 0.05 rad x its kp
            assert after.joint_torque[0, 2].item() == pytest.approx(
                0.05 * models[0].kp[2], rel=0.02
            )
