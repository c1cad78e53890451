"""The training loop of Algorithm 1 around `PPO` and `LocomotionEnv`: K designs x A agents
as one batched environment, rollouts, updates, statistics, checkpoints and resume."""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from coadapt_core import threads, tracking
from coadapt_core.design_space import DesignSpace
from coadapt_core.errors import UserError
from coadapt_core.io import write_atomic
from coadapt_core.learning.checkpoints import (
    CHECKPOINT_FORMAT,
    WEIGHTS_FORMAT,
    match_objectives,
    open_command_inputs,
    read_checkpoint,
    widen_design_input,
)
from coadapt_core.learning.config import TrainConfig
from coadapt_core.learning.ppo import PPO, Dims
from coadapt_core.objective import Objective
from coadapt_core.physics.randomization import RandomizationConfig
from coadapt_core.robot import Robot
from coadapt_core.task.config import TaskConfig
from coadapt_core.task.env import LocomotionEnv


@dataclass
class IterationStats:
    iteration: int
    total_steps: int
    mean_reward: float  # per-step reward over the rollout
    episode_reward: float  # mean return of the episodes that ended (nan if none)
    episode_length_s: float
    tracking_error: float  # mean |v_xy_cmd - v_xy| over the rollout, m/s
    vx: float  # mean base-frame forward speed over envs with a forward command
    command_vx: float
    alternation: float  # share of steps with exactly half of the feet down (NaN: odd leg count)
    fall_rate: float  # falls per env per second
    command_limit: float  # curriculum half-width
    collect_steps_per_s: float
    update_samples_per_s: float
    physics_share: float
    task_share: float
    learner_share: float
    losses: dict[str, float]
    reward_terms: dict[str, float] = field(default_factory=dict)  # mean weighted value per step

    def to_dict(self) -> dict:
        out = {k: v for k, v in self.__dict__.items() if k not in ("losses", "reward_terms")}
        out.update({f"loss/{k}": v for k, v in self.losses.items()})
        out.update({f"reward/{k}": v for k, v in self.reward_terms.items()})
        return out


@dataclass
class _RolloutSums:
    """What one training rollout sums up for its statistics (`Trainer._collect`)."""

    vx_sum: torch.Tensor  # forward speed over envs with a forward command, on the device
    cmd_sum: torch.Tensor
    vx_count: torch.Tensor
    rewards: list[torch.Tensor] = field(default_factory=list)  # per step
    errors: list[torch.Tensor] = field(default_factory=list)
    alternation: list[torch.Tensor] = field(default_factory=list)
    episodes: list[dict] = field(default_factory=list)
    visited: list[torch.Tensor] = field(default_factory=list)  # critic states
    term_sums: dict[str, torch.Tensor] = field(default_factory=dict)


class Trainer:
    """Owns the simulator, the task environment and the learner.

    `set_designs(designs)` places A agents on each of K designs [K, D] (one batched
    environment of K x A robots); `learn(iterations)` runs PPO; `save`/`load` checkpoint all
    of it; `export_weights` writes a small float32 file for deployment and evaluation.
    """

    def __init__(
        self,
        robot: Robot,
        simulator_cls: type,
        objectives: Sequence[Objective] = (),
        *,
        terrain: str = "flat",
        design_space: DesignSpace | None = None,
        train_config: TrainConfig | None = None,
        task_config: TaskConfig | None = None,
        randomization: RandomizationConfig | None = None,
        device: str | None = None,
        seed: int | None = None,
        num_threads: int | None = None,
    ):
        self.robot = robot
        self.simulator_cls = simulator_cls
        self.objectives = list(objectives)
        self.terrain = terrain
        self.design_space = design_space or robot.design_space()
        self.config = train_config or TrainConfig()
        if device is not None:
            self.config.device = device
        if seed is not None:
            self.config.seed = seed
        if self.config.device.startswith("cuda") and not torch.cuda.is_available():
            raise UserError(
                "device 'cuda' requested but no CUDA device is available; use --device cpu",
                field="device",
            )
        self.task_config = task_config or TaskConfig()
        # None: the preset the training configuration names (TrainConfig.extra["randomization"],
        # "table2" unless set; stored in checkpoints, so a resumed run keeps it)
        self.randomization = (
            randomization
            if randomization is not None
            else RandomizationConfig.recorded(self.config.extra)
        )
        #: the thread budget: the physics' threads and the learner's torch threads (given, else
        #: the process's, `coadapt_core.threads.budget()`: --threads or the CPUs it may use;
        #: never the checkpoint's, whose recorded `torch_threads` is not read)
        self.num_threads = (
            threads.check_threads(num_threads, "num_threads")
            if num_threads is not None
            else threads.budget()
        )
        self.device = torch.device(self.config.device)
        self.env: LocomotionEnv | None = None
        self.ppo: PPO | None = None
        self.iteration = 0
        self.total_steps = 0
        self.rng = np.random.default_rng(self.config.seed)
        torch.manual_seed(self.config.seed)
        #: torch threads while updating (the budget) and while collecting (one: the physics
        #: backend's threads own the cores then)
        self.learner_threads = self.num_threads
        self.collect_threads = 1
        self.update_threads_seen: int | None = None  # torch's own count during the last update
        torch.set_num_threads(self.collect_threads)  # outside the update, as while collecting
        self._obs = None
        self._pending_commands: dict | None = None
        self.last_rollout_critic_obs: torch.Tensor | None = None  # [T * N, C] raw, cpu

    # -- environment ------------------------------------------------------------------------
    def sample_designs(self, k: int | None = None) -> np.ndarray:
        """[K, D] designs drawn uniformly from the current design range."""
        return self.design_space.sample(k or self.config.num_designs, self.rng)

    def set_designs(self, designs: np.ndarray, agents: int | None = None) -> None:
        """Place `agents` environments on each design [K, D] (rebuilds the simulator when the
        number of environments changes, else swaps models in place)."""
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        space = self.robot.design_space_for(designs[0])
        designs = space.validate_batch(designs)
        agents = agents or self.config.agents_per_design
        per_env = np.repeat(designs, agents, axis=0)  # [K * A, D], agents of a design adjacent
        if self.env is not None and self.env.num_envs == len(per_env):
            if not np.array_equal(self.env.sim.designs, per_env):
                self.env.set_designs(np.arange(len(per_env)), per_env)
        else:
            commands = self.command_state()  # the curriculum outlives a rebuilt environment
            self.close()
            sim = self.simulator_cls(
                self.robot,
                per_env,
                terrain=self.terrain,
                randomization=self.randomization,
                seed=self.config.seed,
                num_threads=self.num_threads,
            )
            self.env = LocomotionEnv(
                sim,
                self.robot,
                self.task_config,
                self.objectives,
                seed=self.config.seed,
                device=self.device,
            )
            if commands is not None:  # of the environment replaced, or of a loaded checkpoint
                self.env.commands.load_state_dict(commands)
        self.designs = designs
        self.agents = agents
        self._obs = None
        self.ensure_ppo(self.env)

    def ensure_ppo(self, env: LocomotionEnv) -> PPO:
        """Build the learner for `env`'s sizes (or check a loaded one matches them)."""
        dims = Dims(
            env.num_obs,
            env.num_critic_obs,
            env.num_design_obs,
            env.num_actions,
            len(self.objectives),
        )
        if self.ppo is None:
            self.ppo = PPO(dims, self.config, self.device)
        elif self.ppo.dims != dims:
            raise UserError(
                f"the environment's sizes {dims} do not match the policy's {self.ppo.dims}; "
                "was the checkpoint trained for another robot?",
                field="checkpoint",
            )
        return self.ppo

    def command_state(self) -> dict | None:
        """The command curriculum in force: the live environment's, else a loaded
        checkpoint's (None before either exists)."""
        if self.env is not None:
            return self.env.commands.state_dict()
        return self._pending_commands

    def reseed(self, seed: int) -> None:
        """Restart the environment's random streams from `seed` (the task's torch generator,
        which also draws commands, and the simulator's numpy generators); the next `learn`
        resets every environment. After this, training depends only on the checkpointed
        state (networks, normalisers, optimizers, curriculum, counters), the designs and
        `seed`, not on what the environment did before, so a resumed run trains exactly as
        an uninterrupted one."""
        if self.env is None:
            return
        self.env.restart_streams(int(seed))
        self._obs = None

    def close(self) -> None:
        if self.env is not None:
            self.env.sim.close()
            self.env = None

    # -- training ---------------------------------------------------------------------------
    @property
    def samples_per_iteration(self) -> int:
        return self.env.num_envs * self.config.steps_per_env

    def iterations_for(self, steps: int) -> int:
        return max(1, math.ceil(steps / self.samples_per_iteration))

    def learn(
        self, iterations: int, callback: Callable[[IterationStats], None] | None = None
    ) -> IterationStats:
        """Run `iterations` PPO iterations; `callback` sees each one's statistics."""
        if self.env is None:
            self.set_designs(self.sample_designs())
        env, ppo, cfg = self.env, self.ppo, self.config
        ppo.training = True
        if self._obs is None:
            self._obs = env.reset()
        observed = self._obs
        stats = None
        for _ in range(iterations):
            if (
                cfg.design_resample_every
                and self.iteration > 0
                and self.iteration % cfg.design_resample_every == 0
            ):
                self.set_designs(self.sample_designs(len(self.designs)), self.agents)
                observed = env.reset()
            physics0, step0 = env.timing["physics"], env.timing["step"]
            torch.set_num_threads(self.collect_threads)
            start = time.perf_counter()
            observed, sums = self._collect(env, ppo, observed)
            collect_seconds = time.perf_counter() - start
            self.last_rollout_critic_obs = torch.cat(sums.visited).float().cpu()
            torch.set_num_threads(self.learner_threads)
            self.update_threads_seen = torch.get_num_threads()  # what torch says it uses (recorded)
            t_update = time.perf_counter()
            ppo.compute_returns()
            losses = ppo.update()
            update_seconds = time.perf_counter() - t_update
            self.iteration += 1
            samples = env.num_envs * cfg.steps_per_env
            self.total_steps += samples
            physics = env.timing["physics"] - physics0
            task = env.timing["step"] - step0 - physics
            stats = self._iteration_stats(
                sums, losses, samples, collect_seconds, update_seconds, physics, task
            )
            if callback is not None:
                callback(stats)
            tracking.on_training_iteration(
                stats, samples
            )  # TensorBoard / wandb, when one is active
        torch.set_num_threads(self.collect_threads)
        self._obs = observed
        return stats

    def _collect(self, env: LocomotionEnv, ppo: PPO, observed: tuple) -> tuple[tuple, _RolloutSums]:
        """One rollout of `steps_per_env` steps from the observations `observed` (obs,
        critic_obs, design_obs) into the learner's storage; the observations after it and
        the rollout's sums (on the device: no host synchronisation inside the loop)."""
        obs, critic_obs, design_obs = observed
        sums = _RolloutSums(*(torch.zeros((), device=self.device) for _ in range(3)))
        for _ in range(self.config.steps_per_env):
            sums.visited.append(critic_obs)
            actions = ppo.act(obs, critic_obs, design_obs)
            res = env.step(actions)
            ppo.process_env_step(
                res.reward,
                res.done,
                res.timeout,
                res.info["final_critic_obs"],
                res.design_obs,
                res.info["metrics"],
            )
            obs, critic_obs, design_obs = res.obs, res.critic_obs, res.design_obs
            info = res.info
            sums.rewards.append(res.reward.mean())
            lin, command = info["base_lin_vel"], info["command"]
            sums.errors.append((command[:, :2] - lin[:, :2]).norm(dim=-1).mean())
            sums.alternation.append(info["half_stance"].mean())
            forward = (command[:, 0] > 0.1).float()
            sums.vx_sum += (lin[:, 0] * forward).sum()
            sums.cmd_sum += (command[:, 0] * forward).sum()
            sums.vx_count += forward.sum()
            for name, value in info["reward_terms"].items():
                sums.term_sums[name] = sums.term_sums.get(name, 0.0) + value
            if "episode" in info:
                sums.episodes.append(info["episode"])
        return (obs, critic_obs, design_obs), sums

    def _iteration_stats(
        self,
        sums: _RolloutSums,
        losses: dict,
        samples: int,
        collect_seconds: float,
        update_seconds: float,
        physics: float,
        task: float,
    ) -> IterationStats:
        env, cfg, episodes = self.env, self.config, sums.episodes
        total = collect_seconds + update_seconds
        falls = sum(e["fell"] * e["count"] for e in episodes)
        vx_count = sums.vx_count
        return IterationStats(
            iteration=self.iteration,
            total_steps=self.total_steps,
            mean_reward=float(torch.stack(sums.rewards).mean()),
            episode_reward=_weighted_mean(episodes, "reward"),
            episode_length_s=_weighted_mean(episodes, "length_s"),
            tracking_error=float(torch.stack(sums.errors).mean()),
            vx=float(sums.vx_sum / vx_count) if float(vx_count) > 0 else float("nan"),
            command_vx=float(sums.cmd_sum / vx_count) if float(vx_count) > 0 else float("nan"),
            alternation=float(torch.stack(sums.alternation).mean()),
            fall_rate=falls / (env.num_envs * cfg.steps_per_env * env.dt),
            command_limit=float(env.commands.limit),
            collect_steps_per_s=samples / collect_seconds,
            update_samples_per_s=samples * cfg.epochs / update_seconds,
            physics_share=physics / total,
            task_share=task / total,
            learner_share=1.0 - (physics + task) / total,
            losses=losses,
            reward_terms={k: float(v) / cfg.steps_per_env for k, v in sums.term_sums.items()},
        )

    # -- checkpoints ------------------------------------------------------------------------
    def _header(self) -> dict:
        ppo = self.ppo
        return {
            "robot": self.robot.name,
            "simulator": getattr(self.simulator_cls, "name", "?"),
            "terrain": self.terrain,
            "objectives": [o.name for o in self.objectives],
            "design_space": self.design_space.to_dict(),
            "train_config": self.config.to_dict(),
            "task_config": self.task_config.to_dict(),
            "dims": ppo.dims.__dict__,
            "iteration": self.iteration,
            "total_steps": self.total_steps,
        }

    def save(self, path: str | Path) -> Path:
        """Full checkpoint: configs, design range, networks, normalisers, optimizers, counters,
        command curriculum."""
        if self.ppo is None:
            raise UserError(
                "nothing to save: the policy has not been built yet", field="checkpoint"
            )
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        state = {"format": CHECKPOINT_FORMAT, **self._header(), "ppo": self.ppo.state_dict()}
        commands = self.command_state()
        if commands is not None:
            state["commands"] = commands
        state["design_rng"] = self.rng.bit_generator.state  # sample_designs / design resampling
        # written to a temporary file first: a kill mid-write leaves the previous checkpoint
        write_atomic(path, lambda tmp: torch.save(state, tmp))
        return path

    def export_weights(self, path: str | Path) -> Path:
        """Weights only (float32 actor, critic, pseudo-critics and normalisers, plus the
        configs needed to run them and the command curriculum reached): the small file
        shipped with a robot."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        full = self.ppo.state_dict()
        keep = ("actor", "critic", "pseudo_critic", "obs_norm", "critic_norm", "pseudo_norm")
        weights = {
            k: {n: (t.float() if t.is_floating_point() else t).cpu() for n, t in full[k].items()}
            for k in keep
            if full.get(k) is not None
        }
        # the KL-adapted learning rate reached: fine-tuning from this file starts there, not at
        # the configured initial rate (a fresh Adam at 1e-3 knocks a trained policy over)
        weights["learning_rate"] = float(full["learning_rate"])
        state = {"format": WEIGHTS_FORMAT, **self._header(), "ppo": weights}
        commands = self.command_state()
        if (
            commands is not None
        ):  # the command box the policy was trained to (real fitness draws from it)
            state["commands"] = commands
        write_atomic(path, lambda tmp: torch.save(state, tmp))
        return path

    def load(self, path: str | Path, *, optimizers: bool = True, widen: bool = False) -> dict:
        """Restore a checkpoint (or a weights export) written by `save` (`export_weights`).

        `widen=True` also accepts a policy that takes fewer design values than this trainer's
        design space (its leading variables, e.g. the leg scales of the mixed space with motor
        types): see `widen_design_input`. Optimizer states are then not restored."""
        state = read_checkpoint(path)
        wanted = self.design_space.dim
        if widen and int(state["dims"]["num_design"]) < wanted:
            state = widen_design_input(state, wanted)
            optimizers = False
        state, opened = open_command_inputs(state, self.task_config.commands)
        if opened:
            print(
                f"note: '{path}' never saw {' or '.join(opened)} commands vary; their inputs start with zero "
                "weights and the new range's scale",
                file=sys.stderr,
            )
        self.config.hidden = tuple(state["train_config"]["hidden"])
        self.config.activation = state["train_config"]["activation"]
        saved_names = list(state["objectives"])
        names = [o.name for o in self.objectives]
        dims = Dims(**{**state["dims"], "num_metrics": len(names)})
        if self.ppo is None:
            self.ppo = PPO(dims, self.config, self.device)
        elif self.ppo.dims != dims:
            raise UserError(
                f"checkpoint '{path}' has sizes {dims}, the policy here {self.ppo.dims}",
                field="checkpoint",
            )
        ppo_state = dict(state["ppo"])
        same = saved_names == names
        if not same:  # pseudo-critics follow objectives by name; unknown ones start fresh
            ppo_state = match_objectives(ppo_state, saved_names, names, self.ppo)
        self.ppo.load_state_dict(
            ppo_state, optimizers=same and optimizers and state["format"] == CHECKPOINT_FORMAT
        )
        if self.ppo.pseudo_reset:
            print(
                f"note: the pseudo-critics in '{path}' hold non-finite values; they restart from scratch",
                file=sys.stderr,
            )
        self.iteration = int(state["iteration"])
        self.total_steps = int(state["total_steps"])
        if self.env is not None and "commands" in state:
            self.env.commands.load_state_dict(state["commands"])
        self._pending_commands = state.get("commands")
        if "design_rng" in state:
            self.rng.bit_generator.state = state["design_rng"]
        return state


def _weighted_mean(episodes: list[dict], key: str) -> float:
    """Mean of an episode statistic over the episodes that ended (nan when none did)."""
    count = sum(e["count"] for e in episodes)
    return sum(e[key] * e["count"] for e in episodes) / count if count else float("nan")
