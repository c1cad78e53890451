"""The training loop of Algorithm 1 around `PPO` and `LocomotionEnv`: K designs x A agents
as one batched environment, rollouts, updates, statistics, checkpoints and resume."""

from __future__ import annotations

import copy
import math
import sys
import time
from collections.abc import Callable, Sequence
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
    fit_to_trainer,
    match_objectives,
    read_checkpoint,
    weights_of,
)
from coadapt_core.learning.config import TrainConfig
from coadapt_core.learning.iteration_stats import (
    IterationClock,
    IterationStats,
    RolloutSums,
    iteration_stats,
)
from coadapt_core.learning.ppo import PPO, Dims
from coadapt_core.learning.pseudo_critics import PseudoCritics
from coadapt_core.learning.symmetry import MirrorMaps
from coadapt_core.objective import Objective
from coadapt_core.physics.randomization import RandomizationConfig
from coadapt_core.robot import Robot
from coadapt_core.task.config import TaskConfig
from coadapt_core.task.env import LocomotionEnv, normalize_designs


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
        #: training wall clock, s, that `train_until_walks` (`coadapt train --until-walks`)
        #: counts: its checkpoints carry it, so a resumed run's count goes on
        self.train_seconds = 0.0
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
        #: the robot's full spaces (continuous, mixed), asked once: the design inputs' bounds
        self.full_spaces = (robot.design_space(False), robot.design_space(True))
        #: real fitness's environment (`evaluation_env`), beside the training one
        self.eval_env: LocomotionEnv | None = None

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
            self._close_training_env()
            self.env = self._new_env(per_env, self.task_config, num_threads=self.num_threads)
            if commands is not None:  # of the environment replaced, or of a loaded checkpoint
                self.env.commands.load_state_dict(commands)
        self.designs = designs
        self.agents = agents
        self._obs = None
        self.ensure_ppo(self.env)

    def evaluation_env(self, designs: np.ndarray, agents: int, steps: int) -> LocomotionEnv:
        """The environment of real fitness: `agents` environments per design [K, D] (built, or
        its models swapped in place), its commands held from the first step, episodes that
        outlast `steps` policy steps, and the learner built for it. Its random streams are
        the caller's to restart (`coadapt_core.scenarios`)."""
        # checked once, where designs become worlds (`Simulator._check_designs`), before any
        # environment changes
        per_env = np.repeat(designs, agents, axis=0)
        if self.eval_env is not None and self.eval_env.num_envs == len(per_env):
            self.eval_env.set_designs(np.arange(len(per_env)), per_env)
        else:
            if self.eval_env is not None:
                self.eval_env.sim.close()
            task = copy.deepcopy(self.task_config)
            task.commands.resample_seconds = 0.0
            self.eval_env = self._new_env(per_env, task)
        env = self.eval_env
        self.ensure_ppo(env)
        env.cfg.episode_seconds = steps * env.dt + 1.0
        env.max_episode_length = steps + 10
        return env

    def _new_env(self, per_env: np.ndarray, task: TaskConfig, **sim_options) -> LocomotionEnv:
        """A new environment on designs [N, D] with the trainer's robot, terrain,
        randomization and objectives, and `sim_options` for the simulator. Built with the
        trainer's seed, not a call's: the terrain (seeded by the simulator's seed) must not
        depend on which call happened to build it."""
        sim = self.simulator_cls(
            self.robot,
            per_env,
            terrain=self.terrain,
            randomization=self.randomization,
            seed=self.config.seed,
            **sim_options,
        )
        return LocomotionEnv(
            sim, self.robot, task, self.objectives, seed=self.config.seed, device=self.device
        )

    def full_space(self, designs: np.ndarray) -> DesignSpace:
        """The robot's full space (continuous, or mixed when the arity says so) of a batch;
        as `Robot.design_space_for`, without asking the robot again."""
        plain, mixed = self.full_spaces
        arity = np.atleast_2d(np.asarray(designs, dtype=float)).shape[1]
        return mixed if arity == mixed.dim and mixed.dim != plain.dim else plain

    def normalize_designs(self, designs: np.ndarray) -> torch.Tensor:
        """[K, D] designs as the policy reads them (xi, `task.env.normalize_designs` over
        the robot's full space), on the learner's device."""
        space = self.full_space(designs)
        low = torch.as_tensor(space.lower, dtype=torch.float32)
        high = torch.as_tensor(space.upper, dtype=torch.float32)
        return normalize_designs(designs, low, high).to(self.device)

    def pseudo_critics(self) -> PseudoCritics | None:
        """The trained pseudo-critics as the surrogate reads them (None before the learner
        exists or without objectives)."""
        return self.ppo.pseudo_critics() if self.ppo is not None else None

    def critic_states(self, critic_obs: torch.Tensor) -> torch.Tensor:
        """Raw critic states [n, C] (an evaluation buffer's rows) as the critics read them."""
        return self.ppo.normalize_critic_states(critic_obs)

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
        if self.config.symmetry and self.ppo.mirror is None:  # the robot's, or a one-line refusal
            self.ppo.mirror = MirrorMaps.for_env(self.robot, env, self.ppo)
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

    def _close_training_env(self) -> None:
        if self.env is not None:
            self.env.sim.close()
            self.env = None

    def close(self) -> None:
        """Close the training and the evaluation environments' simulators."""
        self._close_training_env()
        if self.eval_env is not None:
            self.eval_env.sim.close()
            self.eval_env = None

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
            clock = IterationClock(
                collect_seconds, update_seconds, physics, env.timing["step"] - step0 - physics
            )
            stats = iteration_stats(
                sums,
                losses,
                clock,
                env=self.env,
                config=cfg,
                iteration=self.iteration,
                total_steps=self.total_steps,
            )
            if callback is not None:
                callback(stats)
            tracking.on_training_iteration(
                stats, samples
            )  # TensorBoard / wandb, when one is active
        torch.set_num_threads(self.collect_threads)
        self._obs = observed
        return stats

    def _collect(self, env: LocomotionEnv, ppo: PPO, observed: tuple) -> tuple[tuple, RolloutSums]:
        """One rollout of `steps_per_env` steps from the observations `observed` (obs,
        critic_obs, design_obs) into the learner's storage; the observations after it and
        the rollout's sums (on the device: no host synchronisation inside the loop)."""
        obs, critic_obs, design_obs = observed
        sums = RolloutSums.zeros(self.device)
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
            sums.add_step(res.reward, res.info)
        return (obs, critic_obs, design_obs), sums

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
        if self.train_seconds > 0:  # only runs that count it (--until-walks) carry it
            state["train_seconds"] = float(self.train_seconds)
        # written to a temporary file first: a kill mid-write leaves the previous checkpoint
        write_atomic(path, lambda tmp: torch.save(state, tmp))
        return path

    def export_weights(self, path: str | Path) -> Path:
        """Weights only (float32 actor, critic, pseudo-critics and normalisers, plus the
        configs needed to run them and the command curriculum reached): the small file
        shipped with a robot."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        weights = weights_of(self.ppo.state_dict())
        state = {"format": WEIGHTS_FORMAT, **self._header(), "ppo": weights}
        commands = self.command_state()
        if commands is not None:  # the command box trained to (real fitness draws from it)
            state["commands"] = commands
        write_atomic(path, lambda tmp: torch.save(state, tmp))
        return path

    def load(self, path: str | Path, *, optimizers: bool = True, widen: bool = False) -> dict:
        """Restore a checkpoint (or a weights export) written by `save` (`export_weights`).

        `widen=True` also accepts a policy that takes fewer design values than this trainer's
        design space (its leading variables, e.g. the leg scales of the mixed space with motor
        types): see `widen_design_input`. Optimizer states are then not restored."""
        state, widened = fit_to_trainer(
            path,
            read_checkpoint(path),
            self.design_space.dim if widen else None,
            self.task_config.commands,
        )
        optimizers = optimizers and not widened
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
                f"note: the pseudo-critics in '{path}' hold non-finite values; "
                "they restart from scratch",
                file=sys.stderr,
            )
        self.iteration = int(state["iteration"])
        self.total_steps = int(state["total_steps"])
        seconds = state.get("train_seconds", 0.0)  # a number, or the count starts again
        self.train_seconds = float(seconds) if isinstance(seconds, int | float) else 0.0
        if self.env is not None and "commands" in state:
            self.env.commands.load_state_dict(state["commands"])
        self._pending_commands = state.get("commands")
        if "design_rng" in state:
            self.rng.bit_generator.state = state["design_rng"]
        return state
