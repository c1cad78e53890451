"""`UniversalPolicyBackend`: the real learner behind the co-adaptation loop, implementing
`coadapt_core.fitness.CoadaptationBackend` — training (Algorithm 1), real fitness
(Algorithm 2) and surrogate fitness from the pseudo-critics (Algorithm 3)."""

from __future__ import annotations

import contextlib
import copy
import time
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from coadapt_core.costs import plain_mean, scenario_se
from coadapt_core.design_space import DesignSpace
from coadapt_core.errors import UserError
from coadapt_core.fitness import RealFitness, TrainingResult
from coadapt_core.learning.checkpoints import read_checkpoint
from coadapt_core.learning.config import TrainConfig
from coadapt_core.learning.evaluate import EvalBuffer, prepare, rollout
from coadapt_core.learning.runner import Runner
from coadapt_core.learning.surrogate import MEMBERS, FittedEnsemble, fit_ensemble, paper_estimate
from coadapt_core.learning.trainer import Trainer
from coadapt_core.objective import Objective
from coadapt_core.physics.randomization import RandomizationConfig
from coadapt_core.robot import Robot
from coadapt_core.task.config import TaskConfig


class UniversalPolicyBackend:
    """The universal policy pi(a | o, xi), its critic and one pseudo-critic per objective.

    Constructor (stable; the co-adaptation loop calls exactly this)::

        UniversalPolicyBackend(robot, simulator_cls, objectives, *, terrain, design_space,
                               agents_per_design, device, seed, checkpoint=None,
                               train_config=None)

    - robot: a `Robot`; simulator_cls: a `Simulator` class; objectives: the `Objective`s whose
      pseudo-critics are trained (their order is the column order of every [K, M] result).
    - design_space: the full design space (normalisation bounds of xi come from the robot).
    - agents_per_design: environments per design in training (K x agents) and the default in
      real fitness.
    - checkpoint: a file written by `save` or `Trainer.save`/`export_weights` to start from
      (resume / fine-tune, Algorithm 4 retraining); pseudo-critics are matched by objective
      name, missing ones start fresh.
    - train_config: `TrainConfig` (sizes, PPO settings; default: the checkpoint's, else the
      defaults); its device, seed and agents_per_design are overridden. The task settings
      (task_config) come from the checkpoint when one is given and none is passed;
      randomization: domain randomization (default: the preset the train config names).

    `train(designs, steps)` trains on the given designs (K of them, `agents_per_design` each)
    for about `steps` interactions; its `TrainingResult.buffer` holds critic states of the
    last rollout. `real_fitness` rolls out the (stochastic, seeded) policy on the scenario set
    of its `seed` (`coadapt_core.scenarios`: agent i of every design gets the same command,
    stratified over the current command box, the same randomization, spawn, noise and action
    noise) and
    returns each design's cost [K, M]: the plain mean over scenarios of each agent's mean
    per-step metric (eq. 4), with standard errors, per-scenario costs [K, A, M] and which
    scenarios fell [K, A], from which callers compute their cost rule
    (`coadapt_core.costs.CostRule`) (set `stochastic_evaluation = False` for the policy
    mean); `surrogate_fitness` averages the pseudo-critics over `samples`
    buffer states with each candidate's xi substituted.

    Exact resume: `train` and `real_fitness` restart every random stream of their
    environment (the simulator's numpy generators, the task's torch generator, the command
    draw) from their `seed`, and reset every environment first, so each is a function of the
    checkpointed state (networks, normalisers, Adam moments, learning rate, command
    curriculum, design RNG, counters), its arguments and the global torch RNG alone. A
    backend that `load`s a `save`d checkpoint therefore trains and evaluates bit-identically
    to the one that saved it (CPU), whatever that one did before.
    """

    #: implements `coadapt_core.fitness.SurrogateEnsemble` (fit_surrogate, surrogate_members)
    surrogate_ensemble = True

    def __init__(
        self,
        robot: Robot,
        simulator_cls: type,
        objectives: Sequence[Objective],
        *,
        terrain: str = "flat",
        design_space: DesignSpace | None = None,
        agents_per_design: int = 50,
        device: str = "cpu",
        seed: int = 0,
        checkpoint: str | None = None,
        train_config: TrainConfig | None = None,
        task_config: TaskConfig | None = None,
        randomization: RandomizationConfig | None = None,
    ):
        saved = read_checkpoint(checkpoint) if checkpoint else None
        if train_config is None:
            train_config = TrainConfig.from_dict(saved["train_config"]) if saved else TrainConfig()
        if task_config is None and saved is not None:
            task_config = TaskConfig.from_dict(saved["task_config"])  # same observation sizes
        config = copy.deepcopy(train_config)
        config.agents_per_design = int(agents_per_design)
        self.trainer = Trainer(
            robot,
            simulator_cls,
            objectives,
            terrain=terrain,
            design_space=design_space,
            train_config=config,
            task_config=task_config,
            randomization=randomization,
            device=device,
            seed=seed,
        )
        self.objectives = list(objectives)
        self.stochastic_evaluation = True
        # common random numbers across designs (docs/coadaptation.md, evaluation protocol)
        self.paired_evaluation = True
        # pseudo-critics fitted to real rounds of the current policy (fit_surrogate)
        self.fitted: FittedEnsemble | None = None
        self.fitted_columns: list[int] | None = None
        self.use_fitted = True  # False: surrogate_fitness is the paper's estimator even when fitted
        self.surrogate_members_count = MEMBERS
        #: further `fit_ensemble` arguments (steps, batch, lr): the fit's defaults when empty
        #: (benchmarks/surrogate_fit_cost.py varies them)
        self.surrogate_fit_options: dict[str, Any] = {}
        if checkpoint:
            self.load(checkpoint)

    @property
    def ppo(self):
        return self.trainer.ppo

    # -- Algorithm 1 ------------------------------------------------------------------------
    def train(self, designs: np.ndarray, steps: int, *, seed: int = 0) -> TrainingResult:
        t0 = time.perf_counter()
        steps0 = self.trainer.total_steps
        torch.manual_seed(seed)
        self.fitted = None  # a new policy: the fit to the last one's real rounds is stale
        self.trainer.set_designs(designs)
        # the environment's streams restart from `seed`, so this phase is a function of the
        # checkpointed state, the designs and the seed (exact resume, docs/coadaptation.md)
        self.trainer.reseed(seed)
        stats = Runner(self.trainer).learn(
            int(steps)
        )  # the runner `coadapt train` drives; it writes nothing here
        visited = self.trainer.last_rollout_critic_obs
        buffer = EvalBuffer(visited) if visited is not None else None
        return TrainingResult(
            steps=self.trainer.total_steps - steps0,
            seconds=time.perf_counter() - t0,
            mean_reward=stats.mean_reward,
            extra={
                "episode_length_s": stats.episode_length_s,
                "tracking_error": stats.tracking_error,
                "vx": stats.vx,
                "collect_steps_per_s": stats.collect_steps_per_s,
                **self.threads_used(),
            },
            buffer=buffer,
        )

    def numerics(self) -> dict[str, str]:
        """The precision actually in force (`TrainConfig.precision` "auto" resolved on this
        device): the PPO loss's forward passes, the pseudo-critics' regression, and the
        policy in rollouts (training and evaluation: float32, never autocast); the device
        (`coadapt_core.numerics` records them with each run)."""
        ppo = self.trainer.ppo
        return {
            "precision": ppo.precision,
            "pseudo_precision": ppo.pseudo_precision,
            "rollout_precision": "float32",
            "device": str(ppo.device),
        }

    def threads_used(self) -> dict[str, int | None]:
        """The threads this phase ran on, as the engines report them: torch's during the
        update and the physics backend's pool (its `num_threads_used` where it has one)."""
        sim = self.trainer.env.sim if self.trainer.env is not None else None
        physics = (
            getattr(sim, "num_threads_used", getattr(sim, "num_threads", None))
            if sim is not None
            else None
        )
        return {"torch_threads": self.trainer.update_threads_seen, "physics_threads": physics}

    # -- Algorithm 2 ------------------------------------------------------------------------
    def _check_objectives(self, objectives: Sequence[Objective]) -> list[int]:
        names = [o.name for o in self.objectives]
        index = []
        for o in objectives:
            if o.name not in names:
                raise UserError(
                    f"objective '{o.name}' has no pseudo-critic in this backend "
                    f"(trained: {', '.join(names)})",
                    field="objective",
                )
            index.append(names.index(o.name))
        return index

    def real_fitness(
        self,
        designs: np.ndarray,
        objectives: Sequence[Objective],
        *,
        agents: int,
        steps: int,
        seed: int = 0,
    ) -> RealFitness:
        t0 = time.perf_counter()
        columns = self._check_objectives(objectives)
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        k = len(designs)
        env = self.trainer.evaluation_env(designs, agents, steps)
        # real fitness is a function of the policy, the curriculum, the designs and `seed`
        # alone: the scenario set of `seed`, paired (common random numbers) or not
        prepare(
            env,
            agents,
            k,
            int(seed),
            paired=self.paired_evaluation,
            command_state=self.trainer.command_state(),
        )
        # the stochastic policy, as in training: the pseudo-critics learn the metric under it,
        # so real and surrogate fitness estimate the same quantity (the mean action's torque
        # and power are lower while the policy's std is large)
        result = rollout(
            self.trainer.ppo.action_distribution,
            env,
            k,
            steps,
            seed=seed,
            stochastic=self.stochastic_evaluation,
        )
        per_scenario = result.per_agent[:, :, columns]  # [K, A, M]
        # the walking gate's tracking measure, per design: the RMS over scenarios of the error
        # of each scenario's mean velocity (v_x, v_y, yaw rate) over the RMS command
        # (coadapt/reliability.py): 0 goes where commanded, 1 is no better than standing still
        command_ms = (
            (env.command.detach().float().cpu().reshape(k, agents, 3) ** 2).sum(-1).mean(1).numpy()
        )
        error_ms = np.asarray(result.mean_velocity_error, dtype=float)
        ratio = np.where(
            command_ms > 1e-4, np.sqrt(error_ms / np.maximum(command_ms, 1e-4)), np.nan
        )
        return RealFitness(
            # the paper's plain mean (Algorithm 2, eq. 4); the caller applies its cost rule
            # (costs.CostRule) to `per_scenario` and `scenario_falls`
            costs=plain_mean(per_scenario),
            buffer=result.buffer,
            interactions=result.steps,
            seconds=time.perf_counter() - t0,
            survival=result.survival,
            per_scenario=per_scenario,
            cost_se=scenario_se(per_scenario, plain_mean),
            fall_rate=1.0 - result.survival,
            scenario_falls=np.asarray(result.falls) > 0,
            tracking_ratio=ratio,
        )

    # -- Algorithm 3 ------------------------------------------------------------------------
    @torch.no_grad()
    def surrogate_fitness(
        self,
        designs: np.ndarray,
        objectives: Sequence[Objective],
        buffer: Any,
        *,
        samples: int,
        seed: int = 0,
    ) -> np.ndarray:
        columns = self._check_objectives(objectives)
        critics = self.trainer.pseudo_critics()
        if critics is None:
            raise UserError(
                "surrogate fitness needs a trained policy with pseudo-critics", field="backend"
            )
        if not isinstance(buffer, EvalBuffer) or len(buffer) == 0:
            raise UserError(
                "surrogate fitness needs a non-empty evaluation buffer from real_fitness or train",
                field="buffer",
            )
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        if self.fitted is not None and self.use_fitted and columns == self.fitted_columns:
            return self.surrogate_members(
                designs, objectives, buffer, samples=samples, seed=seed
            ).mean(axis=0)
        states = self._states(buffer, samples, seed)  # [S, C]
        xi = self.trainer.normalize_designs(designs)  # [K, D]
        with self._learner_threads():
            return paper_estimate(critics, columns, states, xi)

    #: central-difference step of `surrogate_slope`, as a fraction of each variable's
    #: full range (float32 networks: far above their rounding, far below their curvature)
    slope_step = 5e-3

    def surrogate_slope(
        self,
        designs: np.ndarray,
        objectives: Sequence[Objective],
        buffer: Any,
        *,
        samples: int,
        seed: int = 0,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(costs [K, M], gradients [K, M, D]) of `surrogate_fitness` (the fitted ensemble's
        mean when fitted, else the paper's estimator) in the design, by central differences of
        `slope_step` of the full range on one bank of states (`coadapt_core.fitness.
        SurrogateSlope`): every perturbed design is read on the same states, so the
        differences carry no sampling noise."""
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        k, d = designs.shape
        space = self.trainer.full_space(designs)
        h = self.slope_step * np.where(space.upper > space.lower, space.upper - space.lower, 1.0)
        steps = np.diag(h)  # [D, D]
        batch = np.concatenate(
            [
                designs,
                (designs[:, None] + steps).reshape(-1, d),
                (designs[:, None] - steps).reshape(-1, d),
            ]
        )  # [K + 2 K D, D]
        values = self.surrogate_fitness(batch, objectives, buffer, samples=samples, seed=seed)
        m = values.shape[1]
        plus = values[k : k + k * d].reshape(k, d, m)
        minus = values[k + k * d :].reshape(k, d, m)
        grads = ((plus - minus) / (2.0 * h[None, :, None])).transpose(0, 2, 1)  # [K, M, D]
        return values[:k], grads

    # -- pseudo-critics fitted to the current range (issue 16; learning/surrogate.py) -------
    @contextlib.contextmanager
    def _learner_threads(self):
        """The fit and the predictions on the learner's torch threads (every core unless
        configured, as the PPO update), not the single one of collection: no physics runs
        beside them. Their outputs do not depend on the thread count (checked to the bit)."""
        before = torch.get_num_threads()
        torch.set_num_threads(self.trainer.learner_threads)
        try:
            yield
        finally:
            torch.set_num_threads(before)

    def _states(self, buffer: Any, samples: int, seed: int) -> torch.Tensor:
        gen = torch.Generator(device="cpu")
        gen.manual_seed(int(seed))
        rows = torch.randint(len(buffer), (int(samples),), generator=gen)
        return self.trainer.critic_states(buffer.critic_obs[rows])

    def fit_surrogate(
        self,
        designs: np.ndarray,
        costs: np.ndarray,
        objectives: Sequence[Objective],
        buffer: Any,
        *,
        seed: int = 0,
    ) -> None:
        """Fit an ensemble of copies of the pseudo-critics of `objectives` to labelled designs
        [N, D] with their real costs [N, M] (every real round of the current policy), on the
        states of `buffer` (`coadapt_core.learning.surrogate.fit_ensemble`). Until `train`
        changes the policy, `surrogate_fitness` is the members' mean and `surrogate_members`
        their predictions."""
        columns = self._check_objectives(objectives)
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        costs = np.asarray(costs, dtype=float).reshape(len(designs), len(columns))
        ok = np.isfinite(costs).all(axis=1)
        critics = self.trainer.pseudo_critics()
        if critics is None or ok.sum() < 2:
            return
        states = self._states(buffer, min(len(buffer), 65536), seed)
        with self._learner_threads():
            self.fitted = fit_ensemble(
                critics.bank,
                columns,
                critics.scale,
                critics.offset,
                states,
                self.trainer.normalize_designs(designs[ok]),
                torch.as_tensor(costs[ok], dtype=torch.float32),
                members=self.surrogate_members_count,
                seed=seed,
                **self.surrogate_fit_options,
            )
        self.fitted_columns = columns

    @torch.no_grad()
    def surrogate_members(
        self,
        designs: np.ndarray,
        objectives: Sequence[Objective],
        buffer: Any,
        *,
        samples: int,
        seed: int = 0,
    ) -> np.ndarray | None:
        """[E, K, M] each fitted member's surrogate (mean over `samples` buffer states), or
        None before `fit_surrogate` (or after `train`)."""
        columns = self._check_objectives(objectives)
        if self.fitted is None or columns != self.fitted_columns:
            return None
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        states = self._states(buffer, samples, seed)
        with self._learner_threads():
            xi = self.trainer.normalize_designs(designs)
            return self.fitted.predict(states, xi).cpu().numpy()

    # -- checkpoints ------------------------------------------------------------------------
    def save(self, path: str) -> None:
        """Everything `train`/`real_fitness` depend on (see the class docstring), atomically."""
        self.trainer.save(path)

    def load(self, path: str) -> None:
        self.trainer.load(path)
        self.fitted = None

    def close(self) -> None:
        self.trainer.close()
