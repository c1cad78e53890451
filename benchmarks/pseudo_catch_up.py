"""The pseudo-critics paused while a policy learns, then fitted on its rollouts with the policy
frozen (`coadapt train --until-walks --pseudo-catch-up K`), against training them all along:
the learner's seconds per iteration with and without them, and how well each set predicts
the metrics of the policy they end with.

Two trainers from one seed (the new-robot recipe, TaskConfig's defaults or, with
`--two-legs`, the recipe for two legs) train `--iterations` iterations in turn, one each,
each under its own global random states (so each draws what it would alone): A trains the
pseudo-critics all along, B pauses them (`PPO.pseudo_paused`). Their actors, critics and
normalisers must come out equal to the bit (checked: the pause leaves the policy's training
as it was). B then fits its pseudo-critics for the largest of `--fits` iterations with the
policy frozen (`fit_pseudo_critics`, what --until-walks runs once a check walks), scored
after each of `--fits`.

The score: held-out rollouts of that policy (A's trainer reseeded, no network learning,
`--eval-iterations` rollouts back to back, the stochastic policy as in training). At every
state with `--horizon` H steps and no episode end ahead, the target is the truncated
discounted average of each objective's per-step metric, (1 - g) sum_{k<H} g^k P_{t+k} /
(1 - g^H), g the discount; each set's prediction V(s, xi) is set against it (`nrmse`: RMS
error over the targets' standard deviation). Per design of the rollout: the paper's surrogate
(mean of V over the design's states) against the real fitness (mean of P over its steps):
`level_error`, mean |relative error| over the designs, and `spearman` across them. Each
score comes with its standard error and each paused set's difference from the continuous one
with its own, from a bootstrap over the held-out environments (each design's resampled with
replacement, the same draws for every set: `--resamples`).

`--checkpoint FILE` (a walking policy whose pseudo-critics trained all along, as a shipped
`flat.pt`) measures the catch-up where it runs, at a policy that walks: held-out rollouts of
that policy; the pseudo-critics it carries against fresh ones (what the pause leaves)
fitted for each of `--fits` iterations with the policy frozen, the carried ones fitted
alongside on the same rollouts (how far training along would still move them).

    python benchmarks/pseudo_catch_up.py --robot qilin --iterations 200 --fits 25,50,100
    python benchmarks/pseudo_catch_up.py --robot qilin --fits 10,25,50,100 \
        --checkpoint plugins/robots/qilin/policies/flat.pt
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import random
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="qilin")
    parser.add_argument("--sim", default="mujoco")
    parser.add_argument("--objectives", default="tracking,power,torque")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--iterations", type=int, default=200)
    parser.add_argument("--fits", default="25,50,100", help="catch-up lengths scored")
    parser.add_argument("--eval-iterations", type=int, default=30)
    parser.add_argument("--horizon", type=int, default=200)
    parser.add_argument("--two-legs", action="store_true", help="the recipe for two legs")
    parser.add_argument("--resamples", type=int, default=200, help="bootstrap resamples")
    parser.add_argument(
        "--checkpoint",
        help="a walking policy whose pseudo-critics trained all along (a shipped flat.pt): "
        "theirs against fresh ones fitted on it (the module docstring)",
    )
    return parser


class Arm:
    """One trainer, its runner and its own global random states."""

    def __init__(self, args, registry, paused: bool):
        import torch

        from coadapt_core.design_space import DesignSpace
        from coadapt_core.learning.checkpoints import read_checkpoint
        from coadapt_core.learning.config import (
            NEW_ROBOT_TASK_RECIPE,
            TrainConfig,
            new_robot_config,
        )
        from coadapt_core.learning.runner import Runner
        from coadapt_core.learning.trainer import Trainer
        from coadapt_core.settings import apply_overrides
        from coadapt_core.task.config import TaskConfig

        random.seed(args.seed)
        np.random.seed(args.seed)
        task, config, space = TaskConfig(), new_robot_config(seed=args.seed), None
        if args.two_legs:
            task = apply_overrides(task, NEW_ROBOT_TASK_RECIPE[2])
        if args.checkpoint:  # its settings, design range, policy and pseudo-critics
            state = read_checkpoint(args.checkpoint)
            task = TaskConfig.from_dict(state["task_config"])
            config = TrainConfig.from_dict(state["train_config"])
            config.device, config.seed = "cpu", args.seed
            space = DesignSpace.from_dict(state["design_space"])
        names = [n for n in args.objectives.split(",") if n]
        self.trainer = Trainer(
            registry.get("robot", args.robot)(),
            registry.get("simulator", args.sim),
            [registry.get("objective", n)() for n in names],
            terrain="flat",
            design_space=space,
            train_config=config,
            task_config=task,
            num_threads=args.threads,
        )
        self.runner = Runner(self.trainer)
        if args.checkpoint:
            self.runner.init_from(Path(args.checkpoint))
        self.trainer.set_designs(self.trainer.sample_designs())
        self.trainer.ppo.pseudo_paused = paused
        self.names = names
        self.learner: list[float] = []  # compute_returns + update, s per iteration
        self.pseudo: list[float] = []  # the pseudo-critics' part of it
        self.draws = (torch.get_rng_state(), np.random.get_state(), random.getstate())

    @contextlib.contextmanager
    def own_draws(self):
        import torch

        torch.set_rng_state(self.draws[0])
        np.random.set_state(self.draws[1])
        random.setstate(self.draws[2])
        try:
            yield
        finally:
            self.draws = (torch.get_rng_state(), np.random.get_state(), random.getstate())

    def iterate(self, n: int = 1, callback=None) -> None:
        timing = self.trainer.ppo.timing
        for _ in range(n):
            before = timing["returns"] + timing["update"], timing["pseudo"]
            with self.own_draws():
                self.runner.run(1, callback)
            self.learner.append(timing["returns"] + timing["update"] - before[0])
            self.pseudo.append(timing["pseudo"] - before[1])


def _same_policy(a, b) -> bool:
    import torch

    pa, pb = a.trainer.ppo, b.trainer.ppo
    pairs = [
        (pa.actor_net.state_dict(), pb.actor_net.state_dict()),
        (pa.critic_net.state_dict(), pb.critic_net.state_dict()),
        (pa.obs_norm.state_dict(), pb.obs_norm.state_dict()),
        (pa.critic_norm.state_dict(), pb.critic_norm.state_dict()),
    ]
    return all(torch.equal(x[k], y[k]) for x, y in pairs for k in x)


def held_out_rollouts(arm: Arm, iterations: int, seed: int):
    """[N, T] critic states (normalised as the critics read them), designs, metrics and
    episode ends of `iterations` rollouts of the arm's policy, nothing learning."""
    import torch

    trainer, ppo = arm.trainer, arm.trainer.ppo
    trainer.config.design_resample_every = 0  # the designs stay: one metric stream per env
    trainer.reseed(seed)
    frozen, paused = ppo.policy_frozen, ppo.pseudo_paused
    ppo.policy_frozen = ppo.pseudo_paused = True  # a rollout: no GAE, no regression, no norms
    captured = []
    compute = ppo.compute_returns

    def capture():
        td = compute()
        captured.append(td.select("critic_obs", "design_obs", "metrics", ("next", "done")))
        return td

    ppo.compute_returns = capture
    try:
        torch.manual_seed(seed)
        trainer.learn(iterations)
    finally:
        ppo.compute_returns = compute
        ppo.policy_frozen, ppo.pseudo_paused = frozen, paused
    return torch.cat(captured, dim=1)


class Scorer:
    """The held-out targets of a rollout (module docstring) and, per environment, the sums
    each score is made of, so a stratified bootstrap over environments (each design's
    environments resampled with replacement, `resamples` times, the same draws for every
    set of pseudo-critics) gives each score's standard error and each difference's."""

    def __init__(self, rollout, gamma: float, horizon: int, names, resamples: int, seed: int):
        import torch

        metrics = rollout["metrics"].double()  # [N, T, M]
        done = rollout["next", "done"].reshape(metrics.shape[:2])
        t = metrics.shape[1]
        starts = t - horizon + 1
        # S_t = sum_{k, t+k<T} g^k P_{t+k} backwards; the window's sum is S_t - g^H S_{t+H}
        tail = torch.zeros_like(metrics[:, 0])
        sums = torch.empty_like(metrics)
        for step in reversed(range(t)):
            tail = metrics[:, step] + gamma * tail
            sums[:, step] = tail
        after = torch.cat([sums[:, horizon:], torch.zeros_like(sums[:, :1])], dim=1)[:, :starts]
        target = (sums[:, :starts] - gamma**horizon * after) * (1 - gamma) / (1 - gamma**horizon)
        # no episode end after steps t .. t+H-2 (one after the window's last step is fine)
        ended = torch.cat([torch.zeros_like(done[:, :1]), done.long().cumsum(1)], dim=1)
        ok = ((ended[:, horizon - 1 : horizon - 1 + starts] - ended[:, :starts]) == 0).double()
        self.rollout, self.starts, self.names = rollout, starts, names
        self.ok, self.target = ok, target
        self.count = ok.sum(1).numpy()  # [N] scored states per environment
        okm = ok[..., None]
        self.y1 = (target * okm).sum(1).numpy()  # [N, M]
        self.y2 = (target**2 * okm).sum(1).numpy()
        self.real = metrics.mean(1).numpy()  # [N, M] the real fitness's per-env part
        _, design_of = torch.unique(rollout["design_obs"][:, 0], dim=0, return_inverse=True)
        self.design_of = design_of.numpy()
        groups = [np.flatnonzero(self.design_of == j) for j in range(self.design_of.max() + 1)]
        rng = np.random.default_rng(seed)
        draws = [np.arange(len(self.count))]  # the first: the sample itself
        for _ in range(resamples):
            draws.append(np.concatenate([rng.choice(g, len(g)) for g in groups]))
        self.draws = draws

    def parts(self, ppo) -> dict:
        """Per environment: the squared errors' and predictions' sums over its scored states."""
        import torch

        r = self.rollout
        with torch.no_grad():
            pred = ppo.pseudo_values(
                r["critic_obs"][:, : self.starts], r["design_obs"][:, : self.starts]
            ).double()
        okm = self.ok[..., None]
        return {
            "se": ((pred - self.target) ** 2 * okm).sum(1).numpy(),
            "v1": (pred * okm).sum(1).numpy(),
        }

    def scores(self, parts: dict, envs) -> np.ndarray:
        """[M, 3]: nrmse, level_error, spearman over the environments `envs` (with repeats)."""
        from coadapt_core.surrogate_quality import spearman

        n = self.count[envs].sum()
        mse = parts["se"][envs].sum(0) / n
        var = self.y2[envs].sum(0) / n - (self.y1[envs].sum(0) / n) ** 2
        nrmse = np.sqrt(mse / var)
        design = self.design_of[envs]
        out = np.empty((len(self.names), 3))
        # designs with no scored state in this sample (all their windows hold a fall) left out
        kept = [j for j in np.unique(design) if self.count[envs][design == j].sum() > 0]
        real = np.array([self.real[envs][design == j].mean(0) for j in kept])
        surrogate = np.array(
            [
                parts["v1"][envs][design == j].sum(0) / self.count[envs][design == j].sum()
                for j in kept
            ]
        )
        for m in range(len(self.names)):
            level = np.mean(np.abs(surrogate[:, m] - real[:, m]) / np.abs(real[:, m]))
            out[m] = nrmse[m], level, spearman(surrogate[:, m], real[:, m])
        return out

    def boot(self, ppo) -> np.ndarray:
        """[1 + resamples, M, 3]: the sample's scores, then each resample's."""
        parts = self.parts(ppo)
        return np.stack([self.scores(parts, envs) for envs in self.draws])

    def report(
        self, boot: np.ndarray, reference: np.ndarray | None = None, label: str = "continuous"
    ) -> dict:
        """Each objective's scores +- their bootstrap standard errors and, against
        `reference` (the same draws), the differences +- theirs."""
        out = {}
        for m, name in enumerate(self.names):
            row = {}
            for s, stat in enumerate(("nrmse", "level_error", "spearman")):
                row[stat] = [round(float(boot[0, m, s]), 4), round(float(boot[1:, m, s].std()), 4)]
                if reference is not None:
                    d = boot[:, m, s] - reference[:, m, s]
                    row[f"{stat}_minus_{label}"] = [
                        round(float(d[0]), 4),
                        round(float(d[1:].std()), 4),
                    ]
            out[name] = row
        out["states_scored"] = int(self.count.sum())
        return out


def _limit(arm: Arm) -> float:
    """The command curriculum's half-width now."""
    return round(float(arm.trainer.env.commands.limit), 3)


def _mean_se(xs) -> list[float]:
    xs = np.asarray(xs, float)
    return [round(float(xs.mean()), 4), round(float(xs.std(ddof=1) / np.sqrt(len(xs))), 4)]


def from_checkpoint(args, registry) -> dict:
    """--checkpoint: the pseudo-critics it carries (trained all along) against fresh ones
    fitted on its policy, frozen, for each of `--fits` iterations; the carried ones are
    fitted alongside on the same rollouts (their drift: how much training along moves them)."""
    from coadapt_core.experiments.walking_check import fit_pseudo_critics

    held, along, fresh = (Arm(args, registry, paused=False) for _ in range(3))
    with fresh.own_draws():
        fresh.trainer.ppo.reset_pseudo_critics()
    rollout = held_out_rollouts(held, args.eval_iterations, args.seed + 1000)
    scorer = Scorer(
        rollout, held.trainer.config.gamma, args.horizon, held.names, args.resamples, args.seed
    )
    reference = scorer.boot(along.trainer.ppo)
    scores = {"carried (trained all along)": scorer.report(reference)}
    scores["fresh, no fit"] = scorer.report(scorer.boot(fresh.trainer.ppo), reference, "carried")
    done, seconds = 0, {"along": 0.0, "fresh": 0.0}
    for k in sorted(int(x) for x in args.fits.split(",") if x):
        for name, arm in (("along", along), ("fresh", fresh)):
            with arm.own_draws():
                seconds[name] += fit_pseudo_critics(arm.runner, k - done)[1]
        done = k
        moved = scorer.boot(along.trainer.ppo)
        scores[f"carried, fit {k} more"] = scorer.report(moved, reference, "carried")
        fitted = scorer.boot(fresh.trainer.ppo)
        scores[f"fresh, fit {k}"] = {
            "vs_carried": scorer.report(fitted, reference, "carried"),
            "vs_carried_fit_as_long": scorer.report(fitted, moved, "carried_fit_as_long"),
        }
    return {"checkpoint": args.checkpoint, "fit_seconds": seconds, "scores": scores}


def main() -> None:
    args = _parser().parse_args()
    from coadapt_core.launch import apply_omp_wait_policy

    apply_omp_wait_policy()
    from coadapt_core.experiments.walking_check import fit_pseudo_critics
    from coadapt_core.plugins import get_registry
    from coadapt_core.threads import apply_threads

    apply_threads(args.threads)
    registry = get_registry()
    load = [os.getloadavg()]
    start = time.perf_counter()
    if args.checkpoint:
        result = from_checkpoint(args, registry)
        result["wall_seconds"] = round(time.perf_counter() - start, 1)
        result["load_average"] = [*load, os.getloadavg()]
        print(json.dumps(result, indent=2))
        return
    a, b = Arm(args, registry, paused=False), Arm(args, registry, paused=True)
    initial = {k: v.clone() for k, v in b.trainer.ppo.pseudo_critic.state_dict().items()}
    for i in range(args.iterations):
        a.iterate()
        b.iterate()
        if (i + 1) % 25 == 0:
            load.append(os.getloadavg())
            print(f"iteration {i + 1}: load {load[-1][0]:.2f}", file=sys.stderr, flush=True)
    same = _same_policy(a, b)
    unchanged = all(
        bool((v == initial[k]).all()) for k, v in b.trainer.ppo.pseudo_critic.state_dict().items()
    )
    rollout = held_out_rollouts(a, args.eval_iterations, args.seed + 1000)
    scorer = Scorer(
        rollout, a.trainer.config.gamma, args.horizon, a.names, args.resamples, args.seed
    )
    reference = scorer.boot(a.trainer.ppo)
    scores = {"continuous": scorer.report(reference)}
    scores["continuous"]["command_limit"] = _limit(a)  # after the held-out rollouts
    scores["paused, no fit"] = scorer.report(scorer.boot(b.trainer.ppo), reference)
    scores["paused, no fit"]["command_limit"] = _limit(b)
    fits = sorted(int(x) for x in args.fits.split(",") if x)
    done, fit_seconds, fit_learner = 0, 0.0, []
    for k in fits:
        timing = b.trainer.ppo.timing
        before = timing["returns"] + timing["update"]
        with b.own_draws():
            fit_seconds += fit_pseudo_critics(b.runner, k - done)[1]
        fit_learner.append((timing["returns"] + timing["update"] - before) / (k - done))
        done = k
        scores[f"paused, fit {k}"] = scorer.report(scorer.boot(b.trainer.ppo), reference)
        scores[f"paused, fit {k}"]["command_limit"] = _limit(b)
    load.append(os.getloadavg())
    result = {
        "robot": args.robot,
        "seed": args.seed,
        "iterations": args.iterations,
        "samples_per_iteration": a.trainer.samples_per_iteration,
        "policies_equal_to_the_bit": same,
        "paused_heads_unchanged": unchanged,
        "learner_s_per_iteration": {
            "continuous": _mean_se(a.learner),
            "paused": _mean_se(b.learner),
            "ratio_of_means": round(float(np.mean(b.learner) / np.mean(a.learner)), 4),
            "pseudo_share_continuous": round(float(np.sum(a.pseudo) / np.sum(a.learner)), 4),
        },
        "fit": {
            "iterations": fits[-1] if fits else 0,
            "seconds": round(fit_seconds, 1),
            "learner_s_per_iteration": [round(x, 4) for x in fit_learner],
        },
        "scores": scores,
        "eval": {"iterations": args.eval_iterations, "horizon": args.horizon},
        "wall_seconds": round(time.perf_counter() - start, 1),
        "load_average": load,
    }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
