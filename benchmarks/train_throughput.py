"""Training throughput of the universal-policy learner on this machine.

Measures, separately: (1) the physics ceiling — the simulator stepped with fixed targets,
no task and no policy, before and after the training iterations (their mean is used);
(2) rollout collection — policy act + task + physics, env steps/s, with the share of time
in physics, task code and the policy; (3) the PPO update — samples/s (rollout samples per
second of update, all epochs) and sample-epochs/s; (4) the learner's ceiling — the same
networks' forward and backward passes at the update's shapes, each kind timed alone after
every training iteration (`coadapt_core.learning.flops`), and the update's matrix FLOPs.
Prints JSON, with `end_to_end_vs_physics_ceiling` (training env steps/s over the physics
ceiling measured in the same run), `update_vs_learner_ceiling` (the update's achieved GFLOP/s,
compute_returns + update, over the learner's ceiling measured in the same run) and
`pseudo_critic_share` (the pseudo-critics' part of the update's time: their targets in
compute_returns and their regression steps, over compute_returns + update), and
`update_sections`: compute_returns + update split into its network passes and each part that is
not one, seconds an update and share (`update_sections.py`). `--resume`
starts from a checkpoint ('shipped': the robot's shipped policy), so the rollouts are a
walking policy's under its command curriculum rather than a new run's.

    .venv/bin/python benchmarks/train_throughput.py --num-designs 16 --agents 16
    .venv/bin/python benchmarks/train_throughput.py --robot nezha --threads 1 --resume shipped
    .venv/bin/python benchmarks/train_throughput.py --num-designs 128 --agents 32 \
        --device cuda --threads 16
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import numpy as np
from update_sections import UpdateSections


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="kuafu")
    parser.add_argument("--sim", default="mujoco")
    parser.add_argument("--terrain", default="flat")
    parser.add_argument("--num-designs", type=int, default=16)
    parser.add_argument("--agents", type=int, default=16)
    parser.add_argument("--steps-per-env", type=int, default=24)
    parser.add_argument("--epochs", type=int, default=5)
    parser.add_argument("--minibatches", type=int, default=4)
    parser.add_argument(
        "--pseudo-epochs",
        type=int,
        default=None,
        help="pseudo-critic epochs per update (default: TrainConfig's; 0: as PPO's)",
    )
    parser.add_argument(
        "--iterations",
        type=int,
        default=6,
        help="rollouts (and updates) timed after one warm-up (default 6)",
    )
    parser.add_argument("--device", default="cpu")
    parser.add_argument(
        "--threads",
        type=int,
        default=None,
        help=(
            "thread budget of the physics and torch's update "
            "(default: the CPUs this process may use)"
        ),
    )
    parser.add_argument(
        "--torch-threads",
        type=int,
        default=0,
        help="torch threads of the update only (0: --threads)",
    )
    parser.add_argument(
        "--precision",
        default=None,
        choices=["auto", "float32", "bf16"],
        help="numerics of the PPO loss (default: TrainConfig's)",
    )
    parser.add_argument(
        "--pseudo-precision",
        default=None,
        choices=["auto", "float32", "bf16"],
        help="numerics of the pseudo-critic regression (default: TrainConfig's)",
    )
    parser.add_argument(
        "--objectives",
        default="tracking,power,torque",
        help="pseudo-critics to train ('' for none)",
    )
    parser.add_argument(
        "--symmetry",
        action="store_true",
        help="join each minibatch by its left-right mirror image (TrainConfig.symmetry)",
    )
    parser.add_argument(
        "--resume",
        default=None,
        help=(
            "start from this checkpoint ('shipped': the robot's shipped policy): a policy "
            "that walks, under its command curriculum (a new run's box is +-0.3 m/s)"
        ),
    )
    return parser


def _learner_ceiling(trainer, samples: int):
    """The learner's ceiling (`learner_ceiling`) on the update's torch threads."""
    import torch

    from coadapt_core.learning.flops import learner_ceiling

    torch.set_num_threads(trainer.learner_threads)
    try:
        return learner_ceiling(trainer.ppo, samples)
    finally:
        torch.set_num_threads(trainer.collect_threads)


def _learner_figures(ceilings: list, update_seconds: float, samples: int) -> dict:
    """The update's matrix FLOPs, its achieved GFLOP/s (compute_returns + update, mean of
    the timed iterations) and the learner's ceiling measured after each of them (the mean of
    their times for the same FLOPs), with each pass kind's GFLOP/s (the mean of its rates)."""
    flops = ceilings[0].flops
    ceiling_seconds = float(np.mean([c.seconds for c in ceilings]))
    achieved = flops / update_seconds / 1e9
    return {
        "update_mflop_per_sample": round(flops / samples / 1e6, 2),
        "learner_ceiling_gflops_per_s": round(flops / ceiling_seconds / 1e9, 2),
        "learner_ceiling_each_iteration": [round(c.gflops_per_s, 2) for c in ceilings],
        "learner_ceiling_passes_gflops_per_s": {
            k: round(float(np.mean([c.rates[k] for c in ceilings])), 2) for k in ceilings[0].rates
        },
        "update_gflops_per_s": round(achieved, 2),
        "update_vs_learner_ceiling": round(ceiling_seconds / update_seconds, 3),
    }


def main() -> None:
    args = _parser().parse_args()

    # the `coadapt` command's OpenMP wait policy, chosen before torch is imported
    # (coadapt_core/launch.py)
    from coadapt_core.launch import apply_omp_wait_policy

    apply_omp_wait_policy()
    from coadapt_core.learning.config import TrainConfig
    from coadapt_core.learning.runner import Runner
    from coadapt_core.learning.trainer import Trainer
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    import torch

    robot = registry.get("robot", args.robot)()
    sim_cls = registry.get("simulator", args.sim)
    objectives = [registry.get("objective", n)() for n in args.objectives.split(",") if n]
    config = TrainConfig(
        num_designs=args.num_designs,
        agents_per_design=args.agents,
        steps_per_env=args.steps_per_env,
        epochs=args.epochs,
        minibatches=args.minibatches,
        device=args.device,
        symmetry=args.symmetry,
        **{
            k: v
            for k, v in (
                ("precision", args.precision),
                ("pseudo_precision", args.pseudo_precision),
                ("pseudo_epochs", args.pseudo_epochs),
            )
            if v is not None
        },
    )
    trainer = Trainer(
        robot,
        sim_cls,
        objectives,
        terrain=args.terrain,
        train_config=config,
        num_threads=args.threads,
    )
    if (
        args.torch_threads
    ):  # the update on another count than the physics (a measurement of its own)
        trainer.learner_threads = args.torch_threads
    runner = Runner(
        trainer
    )  # what `coadapt train` and the loop's retraining drive (here: nothing written)
    if args.resume:
        path = robot.shipped_policy(args.terrain) if args.resume == "shipped" else args.resume
        if path is None:
            raise SystemExit(f"error: {args.robot} ships no policy for terrain {args.terrain}")
        runner.resume(path)
    t0 = time.perf_counter()
    trainer.set_designs(trainer.sample_designs())
    build_seconds = time.perf_counter() - t0
    env = trainer.env
    n = env.num_envs

    # (1) physics ceiling: the same simulator, default-pose targets, no task, no policy
    sim = env.sim
    targets = sim.default_joint_pos.clone()
    sim.step(targets)
    steps = max(args.steps_per_env * args.iterations, 20)

    def ceiling() -> float:
        t0 = time.perf_counter()
        for _ in range(steps):
            sim.step(targets)
        return n * steps / (time.perf_counter() - t0)

    ceilings = [ceiling()]

    # (2) + (3): PPO iterations, the first one a warm-up
    runner.run(1)
    ppo = trainer.ppo
    samples = n * args.steps_per_env
    learner_ceilings = []
    ppo.profile = True  # exact section timings on a GPU (a synchronisation at each boundary)
    ppo.timing = dict.fromkeys(ppo.timing, 0.0)
    rows = []
    sections = UpdateSections(ppo)
    returns, update = ppo.compute_returns, ppo.update

    def timed(fn):
        def run():
            with sections.active():
                return fn()

        return run

    ppo.compute_returns, ppo.update = timed(returns), timed(update)
    with sections.installed():
        for _ in range(args.iterations):
            runner.run(1, rows.append)
        # after every iteration, outside its timing: on a shared machine the load drifts
        # within seconds, and the ratio compares means taken over the same stretch of time
        learner_ceilings.append(_learner_ceiling(trainer, samples))
    # measured again after training (the simulator keeps its state): on a shared machine the
    # load drifts, and the ratio uses the mean of the two
    sim.reset()
    ceilings.append(ceiling())
    physics_ceiling = float(np.mean(ceilings))
    learner_seconds = ppo.timing["returns"] + ppo.timing["update"]
    pseudo_share = ppo.timing["pseudo"] / learner_seconds if learner_seconds > 0 else 0.0
    collect = float(np.mean([r.collect_steps_per_s for r in rows]))
    update_sample_epochs = float(np.mean([r.update_samples_per_s for r in rows]))
    physics = float(np.mean([r.physics_share for r in rows]))
    task = float(np.mean([r.task_share for r in rows]))
    learner = float(np.mean([r.learner_share for r in rows]))
    collect_s = samples / collect
    update_s = samples * args.epochs / update_sample_epochs
    result = {
        "machine": {
            "cpus": os.cpu_count(),
            "platform": platform.platform(),
            "load_average": os.getloadavg(),
            "torch_threads_update": trainer.learner_threads,
            "torch_threads_collect": trainer.collect_threads,
            "omp_wait": {k: os.environ.get(k) for k in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT")},
            "device": args.device,
            "cuda": torch.cuda.get_device_name(0) if torch.cuda.is_available() else None,
        },
        "setup": {
            "robot": args.robot,
            "sim": args.sim,
            "num_envs": n,
            "pseudo_critics": len(objectives),
            "num_designs": args.num_designs,
            "steps_per_env": args.steps_per_env,
            "epochs": args.epochs,
            "minibatches": args.minibatches,
            "precision": trainer.ppo.precision,
            "pseudo_precision": trainer.ppo.pseudo_precision,
            "physics_threads": getattr(sim, "num_threads_used", None),
            "resume": args.resume,
            "command_limit": env.commands.limit,
            "build_seconds": round(build_seconds, 2),
        },
        "physics_ceiling_env_steps_per_s": round(physics_ceiling),
        "physics_ceiling_before_after": [round(c) for c in ceilings],
        "collection_env_steps_per_s": round(collect),
        "collection_vs_physics_ceiling": round(collect / physics_ceiling, 3),
        "update_samples_per_s": round(samples / update_s),
        "update_sample_epochs_per_s": round(update_sample_epochs),
        "end_to_end_env_steps_per_s": round(samples / (collect_s + update_s)),
        "end_to_end_vs_physics_ceiling": round(
            samples / (collect_s + update_s) / physics_ceiling, 3
        ),
        **_learner_figures(learner_ceilings, learner_seconds / args.iterations, samples),
        "pseudo_critic_share": round(pseudo_share, 3),
        "update_sections": sections.report(args.iterations),
        "time_share": {
            "physics": round(physics, 3),
            "task": round(task, 3),
            "learner": round(learner, 3),
        },
    }
    runner.close()
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
