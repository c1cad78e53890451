"""Time to walk: a robot's universal policy trained from scratch until the walking gate holds.

Trains as `coadapt train` does for a robot with no shipped policy (the new-robot recipe over
TrainConfig's defaults, or with `--start defaults` those defaults alone; TaskConfig's defaults;
the options below over them) and, every `--eval-every` iterations,
writes a checkpoint and evaluates it as `coadapt train`'s verdict does (`evaluate_checkpoint`:
`--eval-agents` agents x `--eval-seconds` under the verdict's command, randomization as in
training) at the nominal design and four corners of the design range (all lower bounds, all
upper, and the two alternating lower/upper by dimension). Walking: the walking gate
(`coadapt_core.coadapt.reliability`) holds at all five. The loop, the check and the random
state's restore after it are `coadapt train --until-walks`'s
(`coadapt_core.experiments.walking_check`). The evaluations and the ceilings are
excluded from the wall clock. Prints one JSON line per evaluation on stderr and, at the end,
JSON: the interactions and training seconds until walking (null if the budget ran out), the
curve, the physics ceiling and the learner's ceiling measured in the same run, the load.

    .venv/bin/python benchmarks/time_to_walk.py --robot qilin                    # the recipe
    .venv/bin/python benchmarks/time_to_walk.py --robot qilin --start defaults   # 128 x 32
    .venv/bin/python benchmarks/time_to_walk.py --robot qilin --max-steps 20000 --eval-every 2
    .venv/bin/python benchmarks/time_to_walk.py --robot qilin --max-seconds 3600 --out runs/ttw

`--max-seconds` bounds the training's wall clock (checked after every iteration; the last
iteration it allows is checked too); `--out` keeps
every check's checkpoint (`check_<iteration>.pt`, for `coadapt eval --checkpoint`).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", required=True)
    parser.add_argument("--sim", default="mujoco")
    parser.add_argument("--terrain", default="flat")
    parser.add_argument("--objectives", default="tracking,power,torque")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=None, help="thread budget (physics, torch)")
    parser.add_argument("--max-steps", type=int, default=20_000_000, help="interaction budget")
    parser.add_argument(
        "--max-seconds", type=float, default=None, help="training wall-clock budget (s)"
    )
    parser.add_argument("--eval-every", type=int, default=50, help="iterations between checks")
    parser.add_argument(
        "--out", type=Path, default=None, help="keep each check's checkpoint here (check_<it>.pt)"
    )
    parser.add_argument("--eval-agents", type=int, default=16)
    parser.add_argument("--eval-seconds", type=float, default=5.0)
    parser.add_argument(
        "--start",
        choices=("recipe", "defaults"),
        default="recipe",
        help="recipe: the new-robot recipe coadapt train starts a robot with no shipped policy "
        "from (NEW_ROBOT_RECIPE); defaults: TrainConfig's defaults (128 x 32, 5 epochs)",
    )
    # TrainConfig's fields (unset: the --start's)
    for name, kind in (
        ("num-designs", int),
        ("agents", int),
        ("steps-per-env", int),
        ("epochs", int),
        ("minibatches", int),
        ("pseudo-epochs", int),
        ("learning-rate", float),
        ("entropy-coef", float),
        ("desired-kl", float),
    ):
        parser.add_argument(f"--{name}", type=kind, default=None)
    return parser


def _config(args):
    from coadapt_core.learning.config import TrainConfig, new_robot_config

    fields = {
        "num_designs": args.num_designs,
        "agents_per_design": args.agents,
        "steps_per_env": args.steps_per_env,
        "epochs": args.epochs,
        "minibatches": args.minibatches,
        "pseudo_epochs": args.pseudo_epochs,
        "learning_rate": args.learning_rate,
        "entropy_coef": args.entropy_coef,
        "desired_kl": args.desired_kl,
    }
    given = {k: v for k, v in fields.items() if v is not None}
    make = new_robot_config if args.start == "recipe" else TrainConfig
    return make(seed=args.seed, **given)


def _physics_ceiling(env, steps: int = 48) -> float:
    """Env steps/s of the training simulator alone (default-pose targets, no task, no policy)."""
    sim = env.sim
    targets = sim.default_joint_pos.clone()
    sim.step(targets)
    start = time.perf_counter()
    for _ in range(steps):
        sim.step(targets)
    rate = env.num_envs * steps / (time.perf_counter() - start)
    sim.reset()
    return rate


def main() -> None:
    args = _parser().parse_args()
    from coadapt_core.launch import apply_omp_wait_policy

    apply_omp_wait_policy()  # as the `coadapt` command, before torch loads
    import torch

    from coadapt_core.experiments.walking_check import (
        check_walking,
        train_until_walks,
        training_draws_kept,
    )
    from coadapt_core.learning.flops import learner_ceiling
    from coadapt_core.learning.runner import Runner
    from coadapt_core.learning.trainer import Trainer
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    robot = registry.get("robot", args.robot)()
    objectives = [registry.get("objective", n)() for n in args.objectives.split(",") if n]
    trainer = Trainer(
        robot,
        registry.get("simulator", args.sim),
        objectives,
        terrain=args.terrain,
        train_config=_config(args),
        num_threads=args.threads,
    )
    runner = Runner(trainer)
    trainer.set_designs(trainer.sample_designs())
    physics = [_physics_ceiling(trainer.env)]
    learner = []
    with tempfile.TemporaryDirectory() as tmp:
        keep = args.out or Path(tmp)
        keep.mkdir(parents=True, exist_ok=True)

        def check() -> dict:
            gate = check_walking(
                trainer,
                keep / f"check_{trainer.iteration}.pt",
                agents=args.eval_agents,
                seconds=args.eval_seconds,
                seed=args.seed,
            )
            with training_draws_kept():  # the ceiling's draws are not the training's either
                torch.set_num_threads(trainer.learner_threads)
                ceiling = learner_ceiling(trainer.ppo, trainer.samples_per_iteration)
                learner.append(ceiling.gflops_per_s)
                torch.set_num_threads(trainer.collect_threads)
            return gate

        done = train_until_walks(
            runner,
            steps=args.max_steps,
            check=check,
            check_every=args.eval_every,
            max_seconds=args.max_seconds,
            on_check=lambda row: print(json.dumps(row), file=sys.stderr, flush=True),
        )
    curve, train_seconds = done.checks, done.train_seconds
    walked = curve[-1] if done.walked else None
    physics.append(_physics_ceiling(trainer.env))
    result = {
        "robot": args.robot,
        "seed": args.seed,
        "train_config": {k: v for k, v in trainer.config.to_dict().items() if k != "extra"},
        "num_envs": trainer.env.num_envs,
        "walked": walked is not None,
        "interactions_to_walk": walked["interactions"] if walked else None,
        "train_seconds_to_walk": walked["train_seconds"] if walked else None,
        "interactions": trainer.total_steps,
        "train_seconds": round(train_seconds, 2),
        "end_to_end_env_steps_per_s": round(trainer.total_steps / train_seconds),
        "physics_ceiling_env_steps_per_s": round(float(np.mean(physics))),
        "end_to_end_vs_physics_ceiling": round(
            trainer.total_steps / train_seconds / float(np.mean(physics)), 3
        ),
        "learner_ceiling_gflops_per_s": round(float(np.mean(learner)), 2),
        "load_average": os.getloadavg(),
        "curve": curve,
    }
    runner.close()
    print(json.dumps(result, indent=2, default=str))


if __name__ == "__main__":
    main()
