"""The PyBullet backend: conformance suite, process model, randomization, terrains, limits."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("pybullet")

import torch
from coadapt_plugins.simulators.pybullet import PyBulletSimulator
from coadapt_plugins.simulators.pybullet import simulator as pb_simulator

from coadapt_core.errors import UserError
from coadapt_core.physics.randomization import RandomizationConfig
from coadapt_core.physics.terrain import make_terrain

NOMINAL = np.array([[1.0, 1.0]])


def fixed(name: str, value: float) -> RandomizationConfig:
    """Randomization with every parameter at its nominal value except `name`."""
    ranges = {k: (v, v) for k, v in RandomizationConfig.NOMINAL.items()}
    ranges[name] = (value, value)
    return RandomizationConfig(**ranges)


def worker_processes_match_in_process() -> None:
    """Three randomized designs stepped in this process and in two worker processes, one
    environment reset midway: the states are equal to the bit, and the workers are gone
    after close."""
    from coadapt_core.plugins import get_registry

    kuafu = get_registry().create("robot", "kuafu")
    designs = kuafu.design_space().sample(3, rng=4)
    finals = {}
    for processes in (0, 2):
        sim = PyBulletSimulator(
            kuafu, designs, randomization=RandomizationConfig(), seed=7, processes=processes
        )
        pids = sim.worker_pids()
        assert len(pids) == processes
        sim.reset()
        targets = sim.default_joint_pos.clone()
        targets[:, 2] += 0.2
        for _ in range(10):
            state = sim.step(targets)
        sim.reset(torch.tensor([1]))
        state = sim.step(targets)
        finals[processes] = state
        params = SimpleNamespace(**sim.env_params.numpy())
        sim.close()
        for pid in pids:
            with pytest.raises(ProcessLookupError):
                os.kill(pid, 0)
    for key in (
        "base_pos",
        "base_quat",
        "joint_pos",
        "joint_vel",
        "joint_torque",
        "foot_contact_force",
    ):
        assert torch.equal(getattr(finals[0], key), getattr(finals[2], key)), key
    assert np.ptp(params.friction) > 0  # randomization really was on


@pytest.mark.slow
def test_worker_processes_match_in_process_and_close_cleanly():
    """Run in a fresh interpreter, as the workers are, and exact, in one try. Until Bullet's
    inverse-dynamics trees were made to go with their bodies (`renew_world`), about one
    interpreter in six had the in-process run leave the workers' after a reset (base
    4.2e-7 m, joint velocity 4.7e-3 rad/s), and this test tried four times."""
    code = (
        "import importlib.util, sys; "
        f"spec = importlib.util.spec_from_file_location('t', {str(Path(__file__))!r}); "
        "m = importlib.util.module_from_spec(spec); spec.loader.exec_module(m); "
        "m.worker_processes_match_in_process(); print('match')"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0 and done.stdout.strip().endswith("match"), done.stderr[-1500:]


def test_a_reloaded_body_gets_its_own_mass_matrix(kuafu):
    """Each design loaded into an environment is what `calculateMassMatrix` (and so the
    armature correction) sees: the translational block of the floating base's mass matrix
    is the new body's total mass. With `removeBody` and a reload into the same world,
    Bullet kept the removed body's inverse-dynamics tree wherever the new body took its
    address: in three runs of this test every one failed from the 5th or 7th reload on
    (a 42.17 kg matrix for bodies of 40.8-42.7 kg)."""
    import pybullet as p

    designs = kuafu.design_space().sample(24, rng=3)
    stale = []
    with PyBulletSimulator(kuafu, designs[:1]) as sim:
        engine = sim._engine
        for k, design in enumerate(designs):
            sim.set_designs(np.array([0]), design[None])
            sim.reset()
            positions = engine._movable_states(0, 0)
            mass = np.array(
                p.calculateMassMatrix(
                    engine.bodies[0], positions.tolist(), physicsClientId=engine.clients[0]
                )
            )
            total = sum(sim.dynamics_info(0)["masses"].values())
            if not np.allclose(np.diag(mass)[3:6], total, rtol=1e-9):
                stale.append((k, float(mass[3, 3]), total))
    assert np.ptp(designs[:, 0]) > 0.2  # the designs differ, and so their masses
    assert not stale, stale


def test_large_batches_go_to_worker_processes(kuafu, monkeypatch):
    monkeypatch.setattr(pb_simulator, "IN_PROCESS_MAX_ENVS", 1)
    with PyBulletSimulator(kuafu, np.repeat(NOMINAL, 2, axis=0), num_threads=2) as sim:
        assert len(sim.worker_pids()) == 2
        pids = sim.worker_pids()
        state = sim.step(sim.default_joint_pos)
        assert state.joint_pos.shape == (2, 8)
    for pid in pids:
        with pytest.raises(ProcessLookupError):
            os.kill(pid, 0)


def test_masses_and_joint_damping_match_the_mujoco_model(kuafu):
    import mujoco

    design = np.array([0.7, 1.3])
    model = kuafu.build(design)
    mj = mujoco.MjModel.from_xml_string(model.text("mjcf"))
    with PyBulletSimulator(kuafu, design[None]) as sim:
        info = sim.dynamics_info(0)
    for name, mass in info["masses"].items():
        body = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_BODY, name)
        assert mass == pytest.approx(mj.body_mass[body], rel=1e-9), name
    assert sum(info["masses"].values()) == pytest.approx(model.total_mass, rel=1e-6)
    dampings = [
        mj.dof_damping[mj.jnt_dofadr[mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, j)]]
        for j in model.joint_names
    ]
    np.testing.assert_allclose(info["joint_damping"], dampings)


def test_friction_restitution_and_com_shift_are_applied(kuafu):
    rand = RandomizationConfig(delay=(0.0, 0.0))
    with PyBulletSimulator(kuafu, np.repeat(NOMINAL, 3, axis=0), randomization=rand, seed=3) as sim:
        sim.reset()
        params = SimpleNamespace(**sim.env_params.numpy())
        with PyBulletSimulator(kuafu, NOMINAL, randomization=RandomizationConfig.off()) as plain:
            base_ipos = np.array(plain.dynamics_info(0)["inertial_pos"])  # the URDF's own base CoM
        assert np.any(base_ipos != 0)
        for e in range(3):
            info = sim.dynamics_info(e)
            # Bullet multiplies both bodies' coefficients; the ground carries 1
            np.testing.assert_allclose(info["friction"], params.friction[e])
            np.testing.assert_allclose(info["restitution"], params.restitution[e])
            np.testing.assert_allclose(
                info["inertial_pos"], base_ipos + params.com_shift[e], atol=1e-9
            )
        assert np.all((params.friction >= 0.5) & (params.friction <= 1.25))
        assert np.all(np.abs(params.com_shift) <= 0.025)


@pytest.mark.parametrize("name", ["motor_strength", "pd_factor"])
def test_torque_scales_with_motor_strength_and_pd_factor(kuafu, name):
    """One physics step from the same state: the torque scales exactly by the factor."""
    torques = []
    for value in (1.0, 0.9):
        with PyBulletSimulator(
            kuafu, NOMINAL, randomization=fixed(name, value), decimation=1, fixed_base=True
        ) as sim:
            sim.reset()
            targets = sim.default_joint_pos + 0.1
            torques.append(sim.step(targets).joint_torque[0].double().numpy())
    np.testing.assert_allclose(torques[1], 0.9 * torques[0], rtol=1e-5)
    assert np.abs(torques[0]).min() > 1.0


def test_delay_holds_the_old_targets_for_the_delay(kuafu):
    """20 ms delay at 5 ms steps: the first 4 physics steps still see the reset targets."""
    runs = {}
    for delay in (0.0, 0.02):
        with PyBulletSimulator(
            kuafu, NOMINAL, randomization=fixed("delay", delay), decimation=1, fixed_base=True
        ) as sim:
            sim.reset()
            assert sim.env_params.delay[0] == pytest.approx(delay)
            moved = sim.default_joint_pos.clone()
            moved[:, 2] += 0.3
            runs[delay] = [sim.step(moved).joint_torque[0, 2].item() for _ in range(6)]
    hold = runs[0.0]
    late = runs[0.02]
    assert hold[0] > 100.0  # the step target acts at once without delay
    assert all(abs(t) < 20.0 for t in late[:4])  # still holding the default pose
    assert late[4] > 100.0  # the delayed target arrives on the fifth step


def test_random_terrain_height_field_is_the_core_grid(kuafu):
    import pybullet as p

    with PyBulletSimulator(kuafu, NOMINAL, terrain="random", seed=5) as sim:
        engine = sim._engine
        terrain = make_terrain("random", seed=5)
        rng = np.random.default_rng(0)
        vertices = (
            np.round(rng.uniform(-9, 9, size=(100, 2)) / terrain.resolution) * terrain.resolution
        )
        hits = p.rayTestBatch(
            [[x, y, 1.0] for x, y in vertices],
            [[x, y, -1.0] for x, y in vertices],
            physicsClientId=engine.clients[0],
        )
        heights = np.array([h[3][2] for h in hits])
        np.testing.assert_allclose(heights, terrain.height_at(vertices), atol=1e-6)
        state = sim.reset()
        # spawned at a drawn point of the field, soles clear of the ground below them
        assert float(state.base_pos[0, :2].abs().max()) > 0.0
        assert torch.all(
            state.foot_pos[0, :, 2] - 0.07
            > torch.as_tensor(terrain.height_at(state.foot_pos[0, :, :2].numpy())) - 1e-3
        )


def test_slope_rises_along_x(kuafu):
    import pybullet as p

    with PyBulletSimulator(kuafu, NOMINAL, terrain="slope") as sim:
        client = sim._engine.clients[0]
        xs = (-2.0, 0.0, 2.0)
        # rays beside the robot (it stands at the origin)
        hits = p.rayTestBatch(
            [[x, 3.0, 5.0] for x in xs], [[x, 3.0, -5.0] for x in xs], physicsClientId=client
        )
        heights = [h[3][2] for h in hits]
        np.testing.assert_allclose(
            heights, np.array([-2.0, 0.0, 2.0]) * np.tan(np.radians(10.0)), atol=1e-6
        )


@pytest.mark.parametrize("kick", [1.0e6, float("nan")])
def test_divergence_resets_and_flags_without_nan(kuafu, kick):
    with PyBulletSimulator(kuafu, np.repeat(NOMINAL, 2, axis=0)) as sim:
        start = sim.reset()
        sim._inject(np.array([1]), kick)
        state = sim.step(sim.default_joint_pos)
        assert state.diverged.tolist() == [False, True]
        for name in (
            "base_pos",
            "base_quat",
            "base_lin_vel",
            "joint_pos",
            "joint_vel",
            "joint_torque",
            "foot_pos",
        ):
            assert torch.isfinite(getattr(state, name)).all()
        # the broken environment is back at its spawn pose
        assert float((state.base_pos[1] - start.base_pos[1]).abs().max()) < 1e-6
        assert not bool(sim.step(sim.default_joint_pos).diverged.any())


def test_fixed_base_hangs_in_the_air(kuafu):
    with PyBulletSimulator(kuafu, NOMINAL, fixed_base=True) as sim:
        start = sim.reset()
        for _ in range(25):
            state = sim.step(sim.default_joint_pos + 0.2)
        assert torch.allclose(state.base_pos, start.base_pos, atol=1e-9)
        assert float(state.base_pos[0, 2]) > 0.5 + kuafu.build(NOMINAL[0]).standing_base_height
        assert not bool(state.foot_contact.any())


def test_bad_input_is_a_user_error(kuafu):
    with pytest.raises(UserError, match="terrain"):
        PyBulletSimulator(kuafu, NOMINAL, terrain="moon")
    with pytest.raises(UserError, match="armature"):
        PyBulletSimulator(kuafu, NOMINAL, armature="magic")
    with PyBulletSimulator(kuafu, NOMINAL) as sim, pytest.raises(UserError, match="joint_targets"):
        sim.step(torch.zeros(1, 3))


def test_missing_pybullet_names_the_extra(kuafu, monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "pybullet" else real(name, *a)
    )
    with pytest.raises(UserError) as info:
        PyBulletSimulator(kuafu, NOMINAL)
    assert (
        str(info.value)
        == "the pybullet simulator needs the pybullet package: pip install 'coadapt[pybullet]'"
    )
    assert isinstance(info.value, ImportError)  # for callers guarding optional backends


def test_registered_as_pybullet():
    from coadapt_core.plugins import load_registry

    assert load_registry().get("simulator", "pybullet") is PyBulletSimulator


def test_set_designs_loads_the_new_robot(kuafu):
    new = np.array([[1.5, 1.5]])
    with PyBulletSimulator(kuafu, np.repeat(NOMINAL, 2, axis=0)) as sim:
        before = sim.dynamics_info(1)["masses"]
        sim.set_designs(np.array([1]), new)
        after = sim.dynamics_info(1)["masses"]
        state = sim.get_state()
    model = kuafu.build(new[0])
    assert after["left_thigh"] > before["left_thigh"]
    assert sum(after.values()) == pytest.approx(model.total_mass, rel=1e-6)
    # standing height of the new legs (+ the 2 mm spawn clearance)
    assert float(state.base_pos[1, 2]) == pytest.approx(
        model.standing_base_height + 0.002, abs=1e-6
    )


@pytest.mark.slow
@pytest.mark.parametrize("ending", ["exit", "kill"])
def test_workers_end_with_the_interpreter(ending, tmp_path):
    """No close(): workers still go when the interpreter exits or is killed outright."""
    import subprocess
    import sys
    import time

    script = (
        "import os, signal, sys, numpy as np\n"
        "from coadapt_plugins.robots.kuafu.robot import Kuafu\n"
        "from coadapt_plugins.simulators.pybullet import PyBulletSimulator\n"
        "sim = PyBulletSimulator(Kuafu(), np.ones((2, 2)), processes=2)\n"
        "print(*sim.worker_pids(), flush=True)\n"
        f"if {ending == 'kill'}: os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=120
    )
    pids = [int(x) for x in out.stdout.split()]
    assert len(pids) == 2, out.stderr
    deadline = time.monotonic() + 10
    alive = pids
    while alive and time.monotonic() < deadline:
        time.sleep(0.1)
        alive = [pid for pid in pids if _alive(pid)]
    assert not alive


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # a zombie (exited, not yet reaped by init) counts as gone
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split()[2] != "Z"
    except FileNotFoundError:
        return False


def test_random_terrain_has_a_safety_floor_beyond_its_edge(kuafu):
    import pybullet as p

    with PyBulletSimulator(kuafu, NOMINAL, terrain="random") as sim:
        client = sim._engine.clients[0]
        (hit,) = p.rayTestBatch([[15.0, 0.0, 1.0]], [[15.0, 0.0, -1.0]], physicsClientId=client)
        assert hit[0] >= 0 and hit[3][2] == pytest.approx(-0.001)


def test_joint_order_other_than_the_urdf_gives_the_same_physics(kuafu):
    """Armature and state must follow `joint_names`, not the URDF's joint order."""
    from dataclasses import replace

    from coadapt_plugins.simulators.pybullet.engine import Engine
    from coadapt_plugins.simulators.pybullet.spec import EnvSpec

    spec = EnvSpec.from_model(kuafu.build(NOMINAL[0]))
    perm = np.array([4, 5, 6, 7, 0, 1, 2, 3])  # right leg first
    swapped = replace(
        spec,
        joint_names=[spec.joint_names[i] for i in perm],
        **{
            k: getattr(spec, k)[perm]
            for k in (
                "default_joint_pos",
                "kp",
                "kd",
                "torque_limit",
                "speed_limit",
                "joint_damping",
                "joint_armature",
                "joint_frictionloss",
            )
        },
    )
    options = dict(
        terrain="flat",
        terrain_seed=0,
        physics_dt=0.005,
        decimation=4,
        fixed_base=True,
        max_delay_steps=0,
    )
    finals = []
    for s, order in ((spec, np.arange(8)), (swapped, perm)):
        engine = Engine([s], **options)
        targets = (spec.default_joint_pos + np.array([0.2, 0.4, 0.5, 0.3, -0.1, -0.3, 0.2, -0.2]))[
            order
        ]
        for _ in range(10):
            state = engine.step(targets[None])
        engine.close()
        finals.append(state["joint_pos"][0][np.argsort(order)])
    np.testing.assert_allclose(finals[1], finals[0], atol=1e-9)
