"""The training loop of Algorithm 1 around `PPO` and `LocomotionEnv`: K designs x A agents
as one batched environment, rollouts, updates, statistics, checkpoints and resume."""

from __future__ import annotations

import math
import os
import pickle  # only for its exception type: nothing is unpickled here
import re
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from coadapt_core import tracking
from coadapt_core.design_space import DesignSpace
from coadapt_core.errors import UserError
from coadapt_core.io import write_atomic
from coadapt_core.learning.config import TrainConfig
from coadapt_core.learning.networks import CriticBank
from coadapt_core.learning.ppo import PPO, Dims
from coadapt_core.objective import Objective
from coadapt_core.physics.randomization import RandomizationConfig
from coadapt_core.robot import Robot
from coadapt_core.task.config import CommandConfig, TaskConfig
from coadapt_core.task.env import LocomotionEnv
from coadapt_core.task.gait import half_stance
from coadapt_core.task.observations import policy_layout, slices

CHECKPOINT_FORMAT = "coadapt-policy-1"
WEIGHTS_FORMAT = "coadapt-policy-weights-1"


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
            raise UserError("device 'cuda' requested but no CUDA device is available; use --device cpu", field="device")
        self.task_config = task_config or TaskConfig()
        # None: the preset the training configuration names (TrainConfig.extra["randomization"],
        # "table2" unless set; stored in checkpoints, so a resumed run keeps it)
        self.randomization = (
            randomization if randomization is not None
            else RandomizationConfig.recorded(self.config.extra)
        )
        self.num_threads = num_threads
        self.device = torch.device(self.config.device)
        self.env: LocomotionEnv | None = None
        self.ppo: PPO | None = None
        self.iteration = 0
        self.total_steps = 0
        self.rng = np.random.default_rng(self.config.seed)
        torch.manual_seed(self.config.seed)
        #: torch threads while updating (every core unless configured) and while collecting
        #: (one: the physics backend's threads own the cores then); see `torch_threads`
        self.learner_threads = int(self.config.torch_threads) or usable_cpus()
        self.collect_threads = 1
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
            self.env = LocomotionEnv(sim, self.robot, self.task_config, self.objectives, seed=self.config.seed, device=self.device)
            if commands is not None:  # of the environment replaced, or of a loaded checkpoint
                self.env.commands.load_state_dict(commands)
        self.designs = designs
        self.agents = agents
        self._obs = None
        self.ensure_ppo(self.env)

    def ensure_ppo(self, env: LocomotionEnv) -> PPO:
        """Build the learner for `env`'s sizes (or check a loaded one matches them)."""
        dims = Dims(env.num_obs, env.num_critic_obs, env.num_design_obs, env.num_actions, len(self.objectives))
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
        self.env.generator.manual_seed(int(seed))
        reseed_simulator(self.env.sim, int(seed))
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

    def learn(self, iterations: int, callback: Callable[[IterationStats], None] | None = None) -> IterationStats:
        """Run `iterations` PPO iterations; `callback` sees each one's statistics."""
        if self.env is None:
            self.set_designs(self.sample_designs())
        env, ppo, cfg = self.env, self.ppo, self.config
        ppo.training = True
        if self._obs is None:
            self._obs = env.reset()
        obs, critic_obs, design_obs = self._obs
        stats = None
        for _ in range(iterations):
            if cfg.design_resample_every and self.iteration > 0 and self.iteration % cfg.design_resample_every == 0:
                self.set_designs(self.sample_designs(len(self.designs)), self.agents)
                obs, critic_obs, design_obs = env.reset()
            physics0, step0 = env.timing["physics"], env.timing["step"]
            torch.set_num_threads(self.collect_threads)
            start = time.perf_counter()
            rewards, errors, alternation = [], [], []
            # on-device sums: no host synchronisation inside the rollout loop
            vx_sum = torch.zeros((), device=self.device)
            cmd_sum = torch.zeros((), device=self.device)
            vx_count = torch.zeros((), device=self.device)
            episodes: list[dict] = []
            visited: list[torch.Tensor] = []
            term_sums: dict[str, torch.Tensor] = {}
            for _ in range(cfg.steps_per_env):
                visited.append(critic_obs)
                actions = ppo.act(obs, critic_obs, design_obs)
                res = env.step(actions)
                ppo.process_env_step(res.reward, res.done, res.timeout, res.info["final_critic_obs"], res.design_obs, res.info["metrics"])
                obs, critic_obs, design_obs = res.obs, res.critic_obs, res.design_obs
                info = res.info
                rewards.append(res.reward.mean())
                lin, command = info["base_lin_vel"], info["command"]
                errors.append((command[:, :2] - lin[:, :2]).norm(dim=-1).mean())
                alternation.append(half_stance(info["foot_contact"]).mean())
                forward = (command[:, 0] > 0.1).float()
                vx_sum += (lin[:, 0] * forward).sum()
                cmd_sum += (command[:, 0] * forward).sum()
                vx_count += forward.sum()
                for name, value in info["reward_terms"].items():
                    term_sums[name] = term_sums.get(name, 0.0) + value
                if "episode" in info:
                    episodes.append(info["episode"])
            collect_seconds = time.perf_counter() - start
            self.last_rollout_critic_obs = torch.cat(visited).float().cpu()
            torch.set_num_threads(self.learner_threads)
            t_update = time.perf_counter()
            ppo.compute_returns()
            losses = ppo.update()
            update_seconds = time.perf_counter() - t_update
            self.iteration += 1
            samples = env.num_envs * cfg.steps_per_env
            self.total_steps += samples
            total = collect_seconds + update_seconds
            physics = env.timing["physics"] - physics0
            task = env.timing["step"] - step0 - physics
            falls = sum(e["fell"] * e["count"] for e in episodes)
            stats = IterationStats(
                iteration=self.iteration,
                total_steps=self.total_steps,
                mean_reward=float(torch.stack(rewards).mean()),
                episode_reward=_weighted_mean(episodes, "reward"),
                episode_length_s=_weighted_mean(episodes, "length_s"),
                tracking_error=float(torch.stack(errors).mean()),
                vx=float(vx_sum / vx_count) if float(vx_count) > 0 else float("nan"),
                command_vx=float(cmd_sum / vx_count) if float(vx_count) > 0 else float("nan"),
                alternation=float(torch.stack(alternation).mean()),
                fall_rate=falls / (env.num_envs * cfg.steps_per_env * env.dt),
                command_limit=float(env.commands.limit),
                collect_steps_per_s=samples / collect_seconds,
                update_samples_per_s=samples * cfg.epochs / update_seconds,
                physics_share=physics / total,
                task_share=task / total,
                learner_share=1.0 - (physics + task) / total,
                losses=losses,
                reward_terms={k: float(v) / cfg.steps_per_env for k, v in term_sums.items()},
            )
            if callback is not None:
                callback(stats)
            tracking.on_training_iteration(stats, samples)  # TensorBoard / wandb, when one is active
        torch.set_num_threads(self.collect_threads)
        self._obs = (obs, critic_obs, design_obs)
        return stats

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
            raise UserError("nothing to save: the policy has not been built yet", field="checkpoint")
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
        if commands is not None:  # the command box the policy was trained to (real fitness draws from it)
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
            raise UserError(f"checkpoint '{path}' has sizes {dims}, the policy here {self.ppo.dims}", field="checkpoint")
        ppo_state = dict(state["ppo"])
        same = saved_names == names
        if not same:  # pseudo-critics follow objectives by name; unknown ones start fresh
            ppo_state["pseudo_critic"] = _remap_heads(ppo_state.get("pseudo_critic"), saved_names, names, self.ppo)
            ppo_state["pseudo_norm"] = _remap_norm(ppo_state["pseudo_norm"], saved_names, names, self.ppo)
        self.ppo.load_state_dict(ppo_state, optimizers=same and optimizers and state["format"] == CHECKPOINT_FORMAT)
        if self.ppo.pseudo_reset:
            print(f"note: the pseudo-critics in '{path}' hold non-finite values; they restart from scratch", file=sys.stderr)
        self.iteration = int(state["iteration"])
        self.total_steps = int(state["total_steps"])
        if self.env is not None and "commands" in state:
            self.env.commands.load_state_dict(state["commands"])
        self._pending_commands = state.get("commands")
        if "design_rng" in state:
            self.rng.bit_generator.state = state["design_rng"]
        return state


#: the first layers, which read the observation (the leading columns of their input) and the
#: design input xi (the last columns): the actor's trunk, the critic's and every
#: pseudo-critic's (per-head layout `heads.<h>.0.weight` [out, in], or the stacked bank's
#: `weight_0` [H, out, in])
_FIRST_LAYER = re.compile(r"^((body|heads\.\d+)\.0\.weight|weight_0)$")


def _map_first_layers(ppo: dict, fn: Callable[[torch.Tensor], torch.Tensor]) -> dict:
    """A copy of a PPO state dict whose first-layer weights (actor, critic, pseudo-critics)
    are replaced by fn(weight)."""
    ppo = dict(ppo)
    for net in ("actor", "critic", "pseudo_critic"):
        if ppo.get(net) is None:
            continue
        ppo[net] = {key: fn(t) if _FIRST_LAYER.match(key) else t for key, t in ppo[net].items()}
    return ppo


def widen_design_input(state: dict, num_design: int) -> dict:
    """A copy of checkpoint `state` whose networks take `num_design` design values instead of
    fewer: the new inputs (appended after the existing ones, as the design space appends its
    variables) get zero weights, so the widened policy, critic and pseudo-critics compute
    exactly what the original did whatever the new variables' values, and training then
    learns how much they matter. Optimizer states are dropped (their shapes change)."""
    old = int(state["dims"]["num_design"])
    if num_design < old:
        raise UserError(
            f"a policy taking {old} design values cannot be narrowed to {num_design}", field="checkpoint"
        )
    out = dict(state)
    out["dims"] = {**state["dims"], "num_design": int(num_design)}
    ppo = {k: v for k, v in state["ppo"].items() if k not in ("optimizer", "pseudo_optimizer")}
    extra = num_design - old
    out["ppo"] = _map_first_layers(
        ppo, lambda w: torch.cat([w, torch.zeros(*w.shape[:-1], extra, dtype=w.dtype)], dim=-1)
    )
    out["widened_from"] = old
    return out


#: below this running variance a normaliser channel counts as constant (never varied)
_CONSTANT_VAR = 1e-8
_COMMAND_NAMES = ("vx", "vy", "yaw-rate")


def open_command_inputs(state: dict, commands: CommandConfig) -> tuple[dict, list[str]]:
    """A copy of checkpoint `state` ready for a task whose commands vary where its training's
    did not (e.g. yaw rates in [-1, 1] for a policy trained at yaw 0), and the names of the
    channels opened.

    A channel that never varied has a running variance of 0, so its normalised input was 0
    throughout training: the weights that read it never learned anything, and the normaliser,
    whose count is the whole training's, would scale a new command by 1/sqrt(eps) and clip it
    at +-clip for millions of steps (a 0.5 rad/s yaw command read as 5 standard deviations,
    whatever its size). Such a channel gets zero first-layer weights in the actor, critic and
    pseudo-critics, so the policy acts exactly as before whatever the new command, and the
    mean and variance of a uniform draw from the new range in both normalisers, so training
    sees the command at its true scale and learns how to use it."""
    ranges = (commands.vx_range, commands.vy_range, commands.yaw_range)
    offset = slices(policy_layout(1, 1))["command"].start  # the same column in o and s
    obs_var = state["ppo"]["obs_norm"]["var"]
    opened = [
        j for j, (lo, hi) in enumerate(ranges)
        if hi > lo and float(obs_var[offset + j]) < _CONSTANT_VAR
    ]
    if not opened:
        return state, []
    out = dict(state)
    ppo = dict(state["ppo"])
    columns = [offset + j for j in opened]

    def zero_columns(w: torch.Tensor) -> torch.Tensor:
        w = w.clone()
        w[..., columns] = 0.0
        return w

    ppo = _map_first_layers(ppo, zero_columns)
    for norm in ("obs_norm", "critic_norm"):
        buffers = dict(ppo[norm])
        mean, var = buffers["mean"].clone(), buffers["var"].clone()
        for j in opened:
            lo, hi = ranges[j]
            mean[offset + j] = 0.5 * (lo + hi)
            var[offset + j] = (hi - lo) ** 2 / 12.0
        buffers["mean"], buffers["var"] = mean, var
        ppo[norm] = buffers
    out["ppo"] = ppo
    return out, [_COMMAND_NAMES[j] for j in opened]


def usable_cpus() -> int:
    """CPU cores this process may run on (its affinity mask where the OS has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def reseed_simulator(sim, seed: int) -> None:
    """Restart a simulator's random streams from `seed` (`Simulator.reseed`, which backends
    may override; the base class restarts every numpy Generator attribute in place)."""
    sim.reseed(int(seed))


def _weighted_mean(episodes: list[dict], key: str) -> float:
    """Mean of an episode statistic over the episodes that ended (nan when none did)."""
    count = sum(e["count"] for e in episodes)
    return sum(e[key] * e["count"] for e in episodes) / count if count else float("nan")


def _remap_heads(saved: dict | None, saved_names: list[str], names: list[str], ppo: PPO) -> dict | None:
    """The pseudo-critic bank's state with head i taken from the saved head of the same
    objective name (a fresh head where the name is new); the saved state may be of the
    per-head layout."""
    if ppo.pseudo_critic is None:
        return None
    out = {k: v.clone() for k, v in ppo.pseudo_critic.state_dict().items()}
    saved = CriticBank.convert_state_dict(saved)
    for i, name in enumerate(names):
        if saved is not None and name in saved_names:
            j = saved_names.index(name)
            for key in out:
                out[key][i] = saved[key][j]
    return out


def _remap_norm(saved: dict, saved_names: list[str], names: list[str], ppo: PPO) -> dict:
    out = {k: v.clone() for k, v in ppo.pseudo_norm.state_dict().items()}
    for i, name in enumerate(names):
        if name in saved_names:
            j = saved_names.index(name)
            out["mean"][i] = saved["mean"][j]
            out["var"][i] = saved["var"][j]
    out["count"] = saved["count"]
    return out


def read_checkpoint(path: str | Path) -> dict:
    """The dict saved by `Trainer.save` / `export_weights`; a one-line `UserError` otherwise.

    Loaded with `weights_only=True`: tensors, numbers, strings and containers only. A file
    carrying anything else (a pickled object, possibly planted to run code) is refused
    without running it."""
    path = Path(path)
    if not path.is_file():
        raise UserError(f"checkpoint '{path}' does not exist", field="checkpoint")
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError:
        raise UserError(
            f"checkpoint '{path}' holds objects other than tensors and plain values; refused "
            "(it is not a coadapt checkpoint, or was altered)", field="checkpoint") from None
    except Exception as exc:
        raise UserError(f"checkpoint '{path}' cannot be read ({type(exc).__name__}); it is damaged or not a checkpoint", field="checkpoint") from None
    if not isinstance(state, dict) or state.get("format") not in (CHECKPOINT_FORMAT, WEIGHTS_FORMAT):
        raise UserError(f"'{path}' is not a coadapt policy checkpoint", field="checkpoint")
    return state
