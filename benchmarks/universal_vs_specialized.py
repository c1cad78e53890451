"""The paper's Tables 4-5 from our own trainer: the reward a specialized policy (trained on one
design) and universal policies (trained on a design range) earn at design (0.5, 0.5) and at
(1.5, 1.5), mean +- std over seeds.

Rows (paper Table 4 at (0.5, 0.5), Table 5 at (1.5, 1.5)):

- at (0.5, 0.5): specialized, universal on [0.5, 1.5]^2, [0.5, 1.0]^2 and [0.5, 0.75]^2;
- at (1.5, 1.5): specialized, universal on [0.5, 1.5]^2, [1.0, 1.5]^2 and [1.25, 1.5]^2.

Every policy gets the same budget (`--steps` environment interactions, `--designs` x
`--agents` environments; a specialized policy's environments all carry its one design). With
`--init-from CKPT` each policy is fine-tuned from that checkpoint (e.g. the shipped flat.pt)
instead of trained from scratch: how the paper's Algorithm 4 narrows a universal policy.

Reward: the task's per-step reward (docs/training.md, weights x dt, clipped at zero, fall
penalty included) summed over `--seconds` of simulated time per agent under a fixed
`--command` (default 0.5 m/s forward), policy mean, Table 2 randomization and noise on,
averaged over `--eval-agents` agents; falls restart the agent and count their penalty. The
paper reports the episode reward of its own task, so only ratios compare with it
(universal / specialized: 54.2 / 58.4 = 0.93 at (0.5, 0.5), 56.5 / 60.8 = 0.93 at (1.5, 1.5)).

    python benchmarks/universal_vs_specialized.py --steps 20000 --seeds 2   # smoke scale
    python benchmarks/universal_vs_specialized.py \\
        --init-from plugins/robots/kuafu/policies/flat.pt \\
        --steps 2000000 --seeds 3 --device cuda --designs 64 --agents 32    # a real table
    python benchmarks/universal_vs_specialized.py ... --json               # one JSON line last

Prints a markdown table and the ratio of each universal row to the specialized one: per seed
(seed s of every row is evaluated on the same scenarios), mean +- standard error over seeds.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

TABLES = {
    (0.5, 0.5): [
        ("specialized", "0.5:0.5,0.5:0.5"),
        ("[0.5, 1.5]^2", "0.5:1.5,0.5:1.5"),
        ("[0.5, 1.0]^2", "0.5:1.0,0.5:1.0"),
        ("[0.5, 0.75]^2", "0.5:0.75,0.5:0.75"),
    ],
    (1.5, 1.5): [
        ("specialized", "1.5:1.5,1.5:1.5"),
        ("[0.5, 1.5]^2", "0.5:1.5,0.5:1.5"),
        ("[1.0, 1.5]^2", "1.0:1.5,1.0:1.5"),
        ("[1.25, 1.5]^2", "1.25:1.5,1.25:1.5"),
    ],
}


def train_policy(args, ranges: str, seed: int):
    from coadapt_plugins.robots.kuafu.robot import Kuafu
    from coadapt_plugins.simulators.mujoco.simulator import MujocoSimulator

    from coadapt_core.learning.checkpoints import read_checkpoint
    from coadapt_core.learning.config import TrainConfig
    from coadapt_core.learning.runner import Runner
    from coadapt_core.learning.trainer import Trainer
    from coadapt_core.task.config import TaskConfig

    robot = Kuafu()
    space = robot.design_space().parse_ranges(ranges)
    state = read_checkpoint(args.init_from) if args.init_from else None
    config = TrainConfig.from_dict(state["train_config"]) if state else TrainConfig()
    config.num_designs, config.agents_per_design = args.designs, args.agents
    config.steps_per_env, config.epochs, config.minibatches = (
        args.steps_per_env,
        args.epochs,
        args.minibatches,
    )
    config.device, config.seed, config.torch_threads = args.device, seed, 0
    task = TaskConfig.from_dict(state["task_config"]) if state else TaskConfig()
    trainer = Trainer(
        robot,
        MujocoSimulator,
        [],
        terrain=args.terrain,
        design_space=space,
        train_config=config,
        task_config=task,
    )
    runner = Runner(trainer)  # what `coadapt train` drives (here: nothing written)
    if args.init_from:
        runner.init_from(args.init_from)
    trainer.set_designs(trainer.sample_designs())
    runner.learn(args.steps)
    return trainer


def reward_at(trainer, design: tuple[float, float], args, seed: int) -> float:
    """Mean over agents of the reward summed over `args.seconds` at `design`."""
    import torch

    trainer.config.seed = seed
    trainer.set_designs(np.array([design]), agents=args.eval_agents)
    env = trainer.env
    env.generator.manual_seed(10_000 + seed)
    env.set_commands(torch.tensor(args.command, dtype=torch.float32))
    obs, _, design_obs = env.reset()
    env.set_commands(torch.tensor(args.command, dtype=torch.float32))
    total = torch.zeros(env.num_envs)
    trainer.ppo.training = False
    with torch.no_grad():
        for _ in range(int(round(args.seconds / env.dt))):
            res = env.step(trainer.ppo.act_inference(obs, design_obs))
            total += res.reward.cpu()
            obs, design_obs = res.obs, res.design_obs
    trainer.ppo.training = True
    return float(total.mean())


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    p.add_argument("--steps", type=int, default=20_000, help="environment interactions per policy")
    p.add_argument("--seeds", type=int, default=2)
    p.add_argument("--designs", type=int, default=4, help="K designs per universal policy")
    p.add_argument("--agents", type=int, default=8, help="environments per design")
    p.add_argument("--steps-per-env", type=int, default=24)
    p.add_argument("--epochs", type=int, default=2)
    p.add_argument("--minibatches", type=int, default=4)
    p.add_argument("--init-from", default=None, help="fine-tune every policy from this checkpoint")
    p.add_argument("--terrain", default="flat")
    p.add_argument("--eval-agents", type=int, default=16)
    p.add_argument("--seconds", type=float, default=10.0)
    p.add_argument(
        "--command", type=lambda s: [float(v) for v in s.split(",")], default=[0.5, 0.0, 0.0]
    )
    p.add_argument("--device", default="cpu")
    p.add_argument("--json", action="store_true")
    return p


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    for name in (
        "steps",
        "seeds",
        "designs",
        "agents",
        "steps_per_env",
        "epochs",
        "minibatches",
        "eval_agents",
    ):
        if getattr(args, name) < 1:
            print(
                f"--{name.replace('_', '-')} must be >= 1, got {getattr(args, name)}",
                file=sys.stderr,
            )
            return 2
    if len(args.command) != 3:
        print("--command must be vx,vy,yaw_rate", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    rows = []
    for design, entries in TABLES.items():
        for label, ranges in entries:
            rewards = []
            for seed in range(args.seeds):
                trainer = train_policy(args, ranges, seed)
                rewards.append(reward_at(trainer, design, args, seed))
                trainer.close()
            rows.append(
                {
                    "design": list(design),
                    "policy": label,
                    "range": ranges,
                    "rewards": rewards,
                    "mean": float(np.mean(rewards)),
                    "std": float(np.std(rewards, ddof=1)) if len(rewards) > 1 else 0.0,
                }
            )
            print(
                f"{design} {label}: {rows[-1]['mean']:.3f} +- {rows[-1]['std']:.3f} "
                f"({len(rewards)} seeds)",
                file=sys.stderr,
                flush=True,
            )
    print(f"| design | policy | reward (mean +- std, {args.seeds} seeds) | / specialized (+- SE) |")
    print("|---|---|---|---|")
    for row in rows:
        spec = next(
            r for r in rows if r["design"] == row["design"] and r["policy"] == "specialized"
        )
        # seed s of every row is evaluated on the same scenarios: the ratio is taken per seed
        ratios = np.array(row["rewards"]) / np.array(spec["rewards"])
        row["ratio"] = float(ratios.mean())
        row["ratio_se"] = (
            float(ratios.std(ddof=1) / np.sqrt(len(ratios))) if len(ratios) > 1 else float("nan")
        )
        print(
            f"| ({row['design'][0]}, {row['design'][1]}) | {row['policy']} | {row['mean']:.2f} +- "
            f"{row['std']:.2f} "
            f"| {row['ratio']:.3f} +- {row['ratio_se']:.3f} |"
        )
    seconds = time.perf_counter() - t0
    print(
        f"{len(rows) * args.seeds} policies x {args.steps} steps, {seconds:.0f} s", file=sys.stderr
    )
    if args.json:
        print(json.dumps({"rows": rows, "seconds": seconds, "args": vars(args)}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
