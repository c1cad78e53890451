"""Throughput of the MuJoCo backend against the raw MuJoCo ceiling, measured in one run.

K designs x A agents of a robot (default Kuafu, 64 x 16 = 1024 environments). In
alternating chunks of policy steps:
  (b) the backend's `step` (actuation law, torque limits, state tensors), holding the
      default pose with small target noise, Table 2 randomization on, recording the
      controls it applies;
  (a) the ceiling: the same environments' models (design + randomization) rolled out by
      `mujoco.rollout` (nthread = threads) from the same states with those recorded
      controls: no Python in the loop, the same contacts.
Throughput is policy steps/s (physics steps / decimation). Prints one JSON line, then a
where-the-time-goes breakdown on stderr. With PyBullet installed and its backend plugin
importable, also times it on a smaller batch.

    .venv/bin/python benchmarks/sim_throughput.py --designs 64 --agents 16 --seconds 20
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import time

import mujoco
import mujoco.rollout
import numpy as np


def _rss_mb() -> float:
    """Current resident set size, MB (Linux /proc; falls back to the peak)."""
    try:
        with open("/proc/self/statm") as fh:
            pages = int(fh.read().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE") / 2**20
    except OSError:
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _robot(name: str):
    from coadapt_core.plugins import get_registry

    return get_registry().create("robot", name)


def _env_states(sim, spec: int) -> tuple[np.ndarray, np.ndarray]:
    """[N, nstate] full physics state and [N, nv] solver warm start of every batch row
    (everything here works in the batch's row order, as the recorded controls are)."""
    batch = sim._live()
    model = sim._ref.model
    out = np.empty((sim.num_envs, mujoco.mj_stateSize(model, spec)))
    warm = np.empty((sim.num_envs, model.nv))
    for i in range(sim.num_envs):
        data = batch.get_data(i)
        mujoco.mj_getState(model, data, out[i], spec)
        warm[i] = data.qacc_warmstart
    return out, warm


def measure_mujoco(
    robot,
    designs: int,
    agents: int,
    seconds: float,
    threads: int | None,
    terrain: str,
    chunk: int,
    seed: int,
) -> dict:
    import torch
    from coadapt_plugins.simulators.mujoco.simulator import MujocoSimulator

    from coadapt_core.physics.randomization import RandomizationConfig

    rng = np.random.default_rng(seed)
    space = robot.design_space()
    unique = space.sample(designs, rng=rng)
    unique[0] = robot.nominal_design()
    env_designs = np.repeat(unique, agents, axis=0)  # [K * A, dim]
    n = env_designs.shape[0]

    rss0 = _rss_mb()
    t = time.perf_counter()
    sim = MujocoSimulator(
        robot,
        env_designs,
        terrain=terrain,
        randomization=RandomizationConfig(),
        seed=seed,
        num_threads=threads,
    )
    build_s = time.perf_counter() - t
    sim.reset()
    default = sim.default_joint_pos
    gen = torch.Generator().manual_seed(seed)
    for _ in range(5):  # warm-up: contacts settle, caches fill
        sim.step(default + 0.02 * torch.randn(default.shape, generator=gen))
    rss_backend = _rss_mb() - rss0
    peak_backend = _peak_rss_mb()

    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    models = [sim._live().get_model(row) for row in range(n)]
    nthread = sim.num_threads_used
    datas = [mujoco.MjData(models[0]) for _ in range(nthread)]
    roller = mujoco.rollout.Rollout(nthread=nthread)

    backend_s = ceiling_s = 0.0
    steps = 0
    sim.timings = dict.fromkeys(sim.timings, 0.0)
    diverged = 0
    deadline = time.perf_counter() + seconds
    while time.perf_counter() < deadline:
        initial, warm = _env_states(sim, spec)
        targets = default + 0.02 * torch.randn((chunk, *default.shape), generator=gen)
        sim.record_controls = []
        t = time.perf_counter()
        for k in range(chunk):
            state = sim.step(targets[k])
            diverged += int(state.diverged.sum())
        backend_s += time.perf_counter() - t
        controls = np.stack(sim.record_controls, axis=1)  # [N, chunk * decimation, nu]
        sim.record_controls = None
        t = time.perf_counter()
        replay, _ = roller.rollout(models, datas, initial, controls, initial_warmstart=warm)
        ceiling_s += time.perf_counter() - t
        if os.environ.get("SIM_THROUGHPUT_DEBUG"):
            gap = np.abs(replay[:, -1, 1 : 1 + sim._ref.model.nq] - sim._qpos).max()
            print(
                f"chunk: backend {backend_s:.2f} s ceiling {ceiling_s:.2f} s replay gap {gap:.2e}",
                file=sys.stderr,
            )
        steps += chunk
    roller.close()
    policy_steps = steps * n
    timings = sim.timings
    accounted = sum(timings.values())
    breakdown = {
        "physics_s": round(timings["physics"], 3),
        "actuation_s": round(timings["actuation"], 3),
        "state_s": round(timings["state"], 3),
        "other_s": round(backend_s - accounted, 3),
        "physics_share": round(timings["physics"] / backend_s, 3),
        "actuation_share": round(timings["actuation"] / backend_s, 3),
        "state_share": round(timings["state"] / backend_s, 3),
    }
    result = {
        "envs": n,
        "designs": designs,
        "agents": agents,
        "terrain": terrain,
        "threads": nthread,
        "decimation": sim.decimation,
        "policy_steps": policy_steps,
        "policy_steps_per_s": round(policy_steps / backend_s, 1),
        "ceiling_policy_steps_per_s": round(policy_steps / ceiling_s, 1),
        "ratio": round(ceiling_s / backend_s, 3),
        "build_s": round(build_s, 2),
        "peak_rss_mb": round(peak_backend, 1),
        "backend_rss_mb": round(rss_backend, 1),
        "rss_per_env_kb": round(rss_backend * 1024 / n, 1),
        "diverged": diverged,
        "breakdown": breakdown,
        "load_avg_1min": round(os.getloadavg()[0], 2),
        "cpu_count": os.cpu_count(),
    }
    sim.close()
    return result


def measure_layouts(
    robot, designs: int, agents: int, threads: int | None, seed: int, reps: int = 5
) -> dict:
    """Physics-only speed of the ways to give each environment its own model, from the same
    states with the same controls (4 physics steps per call, as one policy step):
    the backend's expanded fields, `set_models` with one model per design (no per-env
    randomization possible: `expand` raises on such a batch), `set_models` with a model copy
    per environment, and `mujoco.rollout` over the per-environment models."""
    import torch
    from coadapt_plugins.simulators.mujoco.simulator import MujocoSimulator

    from coadapt_core.physics.randomization import RandomizationConfig

    space = robot.design_space()
    unique = space.sample(designs, rng=seed)
    env_designs = np.repeat(unique, agents, axis=0)
    n = env_designs.shape[0]
    sim = MujocoSimulator(
        robot, env_designs, randomization=RandomizationConfig(), seed=seed, num_threads=threads
    )
    sim.reset()
    for _ in range(10):
        sim.step(sim.default_joint_pos + 0.02 * torch.randn(sim.default_joint_pos.shape))
    nthread = sim.num_threads_used
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    initial, _ = _env_states(sim, spec)
    ctrl = sim._ctrl.copy()
    per_env = [sim._live().get_model(row) for row in range(n)]
    per_design = [sim._compile(d).model for d in unique]
    shared = [per_design[env // agents] for env in sim._env_of_row]
    batches = {"expand (backend)": sim._live()}
    for name, models in (("set_models per design", shared), ("set_models per env", per_env)):
        b = mujoco.batch.Batch(per_design[0], n, nthread=nthread)
        b.set_models(models)
        batches[name] = b
    roller = mujoco.rollout.Rollout(nthread=nthread)
    datas = [mujoco.MjData(per_design[0]) for _ in range(nthread)]
    times: dict[str, list[float]] = {name: [] for name in [*batches, "rollout per env"]}
    nstep = sim.decimation
    nq, nv = sim._ref.model.nq, sim._ref.model.nv
    qpos_cols = slice(1, 1 + nq)  # mjSTATE_FULLPHYSICS: time, qpos, qvel, ...
    qvel_cols = slice(1 + nq, 1 + nq + nv)
    for _ in range(reps):
        for name, b in batches.items():
            # the same starting state everywhere (a reset also clears the solver warm start)
            b.reset(stage=mujoco.mjtStage.mjSTAGE_NONE)
            b.bind("qpos")[:] = initial[:, qpos_cols]
            b.bind("qvel")[:] = initial[:, qvel_cols]
            b.bind("ctrl")[:] = ctrl
            b.forward()
            t = time.perf_counter()
            for _ in range(nstep):
                b.step()
            times[name].append(time.perf_counter() - t)
        t = time.perf_counter()
        roller.rollout(per_env, datas, initial, np.repeat(ctrl[:, None], nstep, axis=1))
        times["rollout per env"].append(time.perf_counter() - t)
    roller.close()
    sim.close()
    return {
        name: {"physics_steps_per_s": round(n * nstep / float(np.median(v)), 1)}
        for name, v in times.items()
    } | {"envs": n, "threads": nthread, "load_avg_1min": round(os.getloadavg()[0], 2)}


def measure_pybullet(robot, envs: int, seconds: float, seed: int) -> dict | None:
    try:
        import pybullet  # noqa: F401

        from coadapt_core.plugins import get_registry

        cls = get_registry().get("simulator", "pybullet")
    except Exception as exc:  # optional: absent package or plugin
        return {"skipped": f"{type(exc).__name__}: {exc}"}

    from coadapt_core.physics.randomization import RandomizationConfig

    designs = robot.design_space().sample(envs, rng=seed)
    with cls(robot, designs, randomization=RandomizationConfig(), seed=seed) as sim:
        sim.reset()
        default = sim.default_joint_pos
        sim.step(default)
        steps = 0
        t = time.perf_counter()
        while time.perf_counter() - t < seconds:
            sim.step(default)
            steps += 1
        elapsed = time.perf_counter() - t
    return {"envs": envs, "policy_steps_per_s": round(steps * envs / elapsed, 1)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robot", default="kuafu")
    parser.add_argument("--designs", type=int, default=64)
    parser.add_argument("--agents", type=int, default=16)
    parser.add_argument(
        "--seconds", type=float, default=20.0, help="wall time of the measured loop (both sides)"
    )
    parser.add_argument("--threads", type=int, default=None, help="default: all cores")
    parser.add_argument("--terrain", default="flat")
    parser.add_argument(
        "--chunk",
        type=int,
        default=2,
        help="policy steps per alternating chunk (small: both sides see the same machine load)",
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--pybullet-envs", type=int, default=16)
    parser.add_argument("--no-pybullet", action="store_true")
    parser.add_argument(
        "--layouts", action="store_true", help="also compare per-environment model layouts"
    )
    args = parser.parse_args(argv)
    for name in ("designs", "agents", "chunk"):
        if getattr(args, name) < 1:
            parser.error(f"--{name} must be >= 1")
    robot = _robot(args.robot)
    result = measure_mujoco(
        robot,
        args.designs,
        args.agents,
        args.seconds * 0.5,
        args.threads,
        args.terrain,
        args.chunk,
        args.seed,
    )
    if args.layouts:
        result["layouts"] = measure_layouts(
            robot, args.designs, args.agents, args.threads, args.seed
        )
    if not args.no_pybullet:
        result["pybullet"] = measure_pybullet(
            robot, args.pybullet_envs, min(10.0, args.seconds / 2), args.seed
        )
    print(json.dumps(result))
    b = result["breakdown"]
    print(
        f"where the time goes ({result['envs']} envs, {result['threads']} threads, load "
        f"{result['load_avg_1min']}): "
        f"physics {b['physics_share']:.0%}, actuation {b['actuation_share']:.0%}, "
        f"state extraction {b['state_share']:.0%}, other {b['other_s']:.2f} s; "
        f"backend {result['policy_steps_per_s']:.0f} vs ceiling "
        f"{result['ceiling_policy_steps_per_s']:.0f} "
        f"policy steps/s = {result['ratio']:.2f}",
        file=sys.stderr,
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
