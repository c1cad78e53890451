"""Real evaluation (Algorithm 2) on a scenario set: readying an environment for a batch of
designs (`prepare`: the scenarios of one seed, paired or not) and rolling a policy out on it,
deterministically (the policy mean) or stochastically: per-design mean objective metrics,
survival, speed, and the evaluation buffer R_eval of critic states the surrogate (Algorithm 3)
averages over. The policy is any callable from observations to a Gaussian's (mean, std), such
as `PPO.action_distribution`: this room needs no learner.

Scenarios (docs/coadaptation.md, "Evaluation protocol"): agent i of every design gets scenario
i, that is its command (stratified over the command box), its Table 2 draw and spawn point
(held by the simulator), its initial gait phase and its observation- and action-noise streams
(`PairedStreams`, which the task holds as its `SharedStreams`). They reach the environment
through its own methods (`LocomotionEnv.restart_streams`, `draw_commands`,
`draw_randomization`, `fix_scenarios`, `set_commands`, `use_scenarios`); the seed of a run's
set block by block is `scenarios.seeds.scenario_seed`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch

from coadapt_core.errors import UserError
from coadapt_core.statefile import register_dataclass
from coadapt_core.task.env import LocomotionEnv

#: a policy for `rollout`: (raw observations [N, O], normalised designs [N, D]) -> the mean and
#: standard deviation [N, A] of its Gaussian over actions (`PPO.action_distribution`)
Policy = Callable[[torch.Tensor, torch.Tensor], tuple[torch.Tensor, torch.Tensor]]


@register_dataclass  # saved in run folders as arrays (buffer-<n>.npz), never pickled
@dataclass
class EvalBuffer:
    """R_eval: critic states (raw, un-normalised) visited by the policy."""

    critic_obs: torch.Tensor  # [S, C] float32, cpu

    def __len__(self) -> int:
        return int(self.critic_obs.shape[0])


@dataclass
class RolloutResult:
    metrics: np.ndarray  # [K, M] mean per-step metric of each design over agents and steps
    survival: np.ndarray  # [K] share of agents that never fell
    vx: np.ndarray  # [K] mean base-frame forward speed (steps before an agent's first fall)
    tracking_error: np.ndarray  # [K] mean e_v^2 + e_w^2 (steps before the first fall)
    alternation: (
        np.ndarray
    )  # [K] share of steps with exactly half of the feet down (NaN: odd leg count)
    buffer: EvalBuffer
    steps: int  # environment interactions
    per_agent: np.ndarray | None = None  # [K, A, M] each agent's mean per-step metric
    falls: np.ndarray | None = None  # [K, A] falls of each agent (it restarts after each)
    fall_metric: np.ndarray | None = None  # [K, M] mean per-step metric accrued on fall steps
    #: [K] mean over agents of |mean velocity - mean command|^2 over (v_x, v_y, yaw rate), each
    #: agent's means over its steps before its first fall: a gait's oscillation and the
    #: policy's action noise average out, a robot that stands still scores |command|^2
    mean_velocity_error: np.ndarray | None = None
    yaw_rate: np.ndarray | None = (
        None  # [K] mean base yaw rate, rad/s (steps before an agent's first fall)
    )
    #: [K, A, 3] each agent's mean (v_x, v_y, yaw rate) before its first fall (the spread
    #: behind `vx` and `yaw_rate`: their standard errors)
    per_agent_velocity: np.ndarray | None = None


class _Tally:
    """Per-environment sums of a rollout (on the device), and the `RolloutResult` from them."""

    def __init__(self, n: int, m: int, device: torch.device):
        z = lambda *shape: torch.zeros(*shape, device=device)  # noqa: E731
        self.metric_sum = z(n, m)
        self.alive = torch.ones(n, dtype=torch.bool, device=device)
        self.alive_steps = z(n)
        self.vx_sum = z(n)
        self.err_sum = z(n)
        self.vel_sum = z(n, 3)  # (v_x, v_y, yaw rate) and command sums
        self.cmd_sum = z(n, 3)
        self.alt_sum = z(n)
        self.falls = z(n)
        self.fall_metric = z(n, m)

    def add(self, info: dict) -> None:
        """One step's `info` (`LocomotionEnv.step`): speeds and errors count until an
        environment's first fall, metrics throughout."""
        self.metric_sum += info["metrics"]
        lin, command = info["base_lin_vel"], info["command"]
        err = ((command[:, :2] - lin[:, :2]) ** 2).sum(-1) + (
            command[:, 2] - info["base_ang_vel"][:, 2]
        ) ** 2
        alive_f = self.alive.float()
        self.vx_sum += lin[:, 0] * alive_f
        self.err_sum += err * alive_f
        self.vel_sum += (
            torch.cat([lin[:, :2], info["base_ang_vel"][:, 2:3]], dim=-1) * alive_f[:, None]
        )
        self.cmd_sum += command * alive_f[:, None]
        self.alt_sum += info["half_stance"] * alive_f
        self.alive_steps += alive_f
        self.alive &= ~info["terminated"]
        fell = info["terminated"].float()
        self.falls += fell
        self.fall_metric += info["metrics"] * fell[:, None]

    def result(self, num_designs: int, steps: int, buffer: EvalBuffer) -> RolloutResult:
        n, m = self.metric_sum.shape
        agents = n // num_designs

        def per_design(x: torch.Tensor) -> np.ndarray:
            return x.reshape(num_designs, agents, *x.shape[1:]).mean(dim=1).cpu().numpy()

        safe = self.alive_steps.clamp(min=1.0)
        vel_sum = self.vel_sum
        return RolloutResult(
            metrics=per_design(self.metric_sum / steps),
            survival=per_design(self.alive.float()),
            vx=per_design(self.vx_sum / safe),
            tracking_error=per_design(self.err_sum / safe),
            alternation=per_design(self.alt_sum / safe),
            buffer=buffer,
            steps=n * steps,
            per_agent=(self.metric_sum / steps).reshape(num_designs, agents, m).cpu().numpy(),
            falls=self.falls.reshape(num_designs, agents).cpu().numpy(),
            fall_metric=per_design(self.fall_metric / steps),
            mean_velocity_error=per_design(
                ((vel_sum - self.cmd_sum) / safe[:, None]).pow(2).sum(-1)
            ),
            yaw_rate=per_design(vel_sum[:, 2] / safe),
            per_agent_velocity=(vel_sum / safe[:, None])
            .reshape(num_designs, agents, 3)
            .cpu()
            .numpy(),
        )


@torch.no_grad()
def rollout(
    policy: Policy,
    env: LocomotionEnv,
    num_designs: int,
    steps: int,
    *,
    buffer_rows: int = 100_000,
    seed: int = 0,
    stochastic: bool = False,
    on_step=None,
) -> RolloutResult:
    """Run `steps` steps of `policy` on `env`, whose environments are `num_designs`
    consecutive groups of agents (as `Trainer.set_designs` lays them out). Actions are the
    policy mean, or samples of its Gaussian when `stochastic` (seeded by `seed`, as are the
    observation noise and the buffer sample)."""
    n = env.num_envs
    tally = _Tally(n, env.num_metrics, env.device)
    gen = torch.Generator(device="cpu")
    gen.manual_seed(int(seed))
    env.generator.manual_seed(int(seed))
    action_gen = torch.Generator(device=env.device)
    action_gen.manual_seed(int(seed) + 1)
    obs, critic, design_obs = env.reset()
    per_step = max(1, -(-buffer_rows // max(steps, 1)))
    kept: list[torch.Tensor] = []
    for _ in range(steps):
        if per_step >= n:
            kept.append(critic.float().cpu())
        else:
            kept.append(
                critic[torch.randperm(n, generator=gen)[:per_step].to(env.device)].float().cpu()
            )
        loc, scale = policy(obs, design_obs)
        if stochastic:
            # paired evaluation: agent i of every design gets the same action noise
            actions = loc + scale * env.paired_draw(tuple(loc.shape), action_gen).to(loc.device)
        else:
            actions = loc
        res = env.step(actions)
        tally.add(res.info)
        if on_step is not None:
            on_step(env)
        obs, critic, design_obs = res.obs, res.critic_obs, res.design_obs
    return tally.result(num_designs, steps, EvalBuffer(torch.cat(kept)[:buffer_rows]))


@dataclass(frozen=True)
class PairedStreams:
    """The task's random numbers of one scenario set, shared by every design: environment
    k * agents + i draws what environment i draws (`LocomotionEnv.use_scenarios`): its gait
    phase `phase[i]` at every episode start, its observation noise from a generator keyed
    by `seed` and the steps since the last full reset alone (the same noise however often a
    step is observed, whoever fell), and its action noise (`LocomotionEnv.paired_draw`)."""

    agents: int
    seed: int
    phase: torch.Tensor  # [agents] initial gait phases in [0, 1)

    @classmethod
    def draw(cls, agents: int, seed: int, device: torch.device) -> PairedStreams:
        gen = torch.Generator(device=device)
        gen.manual_seed(int(seed))
        return cls(int(agents), int(seed), torch.rand(int(agents), generator=gen, device=device))


def apply_scenarios(
    env: LocomotionEnv,
    agents: int,
    designs: int,
    seed: int,
    *,
    command_state: dict | None = None,
    commands: torch.Tensor | None = None,
) -> torch.Tensor:
    """Give the `designs` consecutive groups of `agents` environments of `env` the scenario
    set of `seed`: agent i of each group gets scenario i, that is its command (`commands`
    [agents, 3] when given, else stratified over the command box of `command_state`, the
    curriculum's, or the env's own when None), its randomization draw (Table 2) and spawn
    point, its initial gait phase and its observation- and action-noise streams
    (`PairedStreams`). A scenario depends on `seed` and i alone, not on the designs or on the
    other agents. Returns the commands [agents, 3]."""
    agents = int(agents)
    if agents < 1 or env.num_envs % agents:
        raise UserError(
            f"paired scenarios: {env.num_envs} environments do not split into groups "
            f"of {agents} agents",
            field="agents",
        )
    if commands is None:
        commands = env.draw_commands(
            agents, seed, command_state=command_state, paired=True
        )  # [A, 3]
    commands = torch.as_tensor(commands, dtype=torch.float32, device=env.device).reshape(agents, 3)
    env.set_commands(commands.repeat(designs, 1))
    rng = np.random.default_rng([int(seed), 0xC0])  # the randomization draw of each scenario
    params = env.draw_randomization(agents, rng)
    spawn = rng.random((agents, 2))
    streams = PairedStreams.draw(agents, int(seed), env.device)
    env.fix_scenarios(params.repeat(designs), np.tile(spawn, (designs, 1)))
    env.use_scenarios(streams)
    return commands


def apply_unpaired(
    env: LocomotionEnv, agents: int, designs: int, seed: int, *, command_state: dict | None = None
) -> None:
    """The protocol before paired evaluation, kept to measure what pairing buys
    (benchmarks/fitness_noise.py --protocol unpaired): commands drawn independently per
    agent from the box (shared by the designs of one call), every randomization draw and
    noise stream independent per environment."""
    commands = env.draw_commands(agents, seed, command_state=command_state, paired=False)
    env.set_commands(commands.repeat(designs, 1))
    env.fix_scenarios(None)
    env.use_scenarios(None)


def prepare(
    env: LocomotionEnv,
    agents: int,
    designs: int,
    seed: int,
    *,
    paired: bool = True,
    command_state: dict | None = None,
) -> None:
    """Ready `env` (`designs` consecutive groups of `agents` environments) for a real
    evaluation on the scenario set of `seed`: the simulator's streams restart from `seed`
    (the task's own generator restarts with the rollout's seed), then the scenarios are
    applied, paired (`apply_scenarios`) or not (`apply_unpaired`), under the command
    curriculum `command_state`. What follows is a function of the policy, the curriculum,
    the designs and `seed` alone, whatever earlier calls drew."""
    env.restart_streams(seed, task=False)
    if paired:
        apply_scenarios(env, agents, designs, seed, command_state=command_state)
    else:
        apply_unpaired(env, agents, designs, seed, command_state=command_state)
