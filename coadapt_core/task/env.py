"""`LocomotionEnv`: the locomotion task on any `Simulator`, as one batched vector
environment (commands, gait clock and Raibert reference, observations, rewards, objective
metrics, termination and auto-reset), torch tensors on the device given (the simulator's by
default); and `normalize_designs`, the design input xi that it and the learner read. What it
derives from the designs lives in `task.designs`, the episodes' statistics in
`task.episodes`, the observation layouts and the step's record in `task.observations`."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np
import torch

from coadapt_core.objective import Objective, StepBatch
from coadapt_core.physics.simulator import SimState, Simulator
from coadapt_core.robot import Robot
from coadapt_core.task import episodes
from coadapt_core.task import observations as layout
from coadapt_core.task.commands import CommandSampler
from coadapt_core.task.config import TaskConfig
from coadapt_core.task.designs import DesignInputs
from coadapt_core.task.gait import GaitClock, half_stance
from coadapt_core.task.observations import StepResult
from coadapt_core.task.rewards import RewardInputs, combine, compute_terms
from coadapt_core.task.scenario_hooks import ScenarioHooks, SharedStreams


def normalize_designs(
    designs: np.ndarray | torch.Tensor, low: torch.Tensor, high: torch.Tensor
) -> torch.Tensor:
    """[n, D] designs as the policy reads them (xi): each variable mapped linearly from its
    bounds [low, high] (the robot's full design space) to [-1, 1], 0 where the bounds meet;
    float32 on the bounds' device. The one normalisation: the environment's design observation
    and the learner's surrogate both use it."""
    xi = torch.as_tensor(np.asarray(designs, dtype=np.float32), device=low.device)
    width = high - low
    safe = torch.where(width > 0, width, torch.ones_like(width))
    return torch.where(width > 0, 2.0 * (xi - low) / safe - 1.0, torch.zeros_like(xi))


class LocomotionEnv(ScenarioHooks):
    """The task, simulator-agnostic. `step` returns a `StepResult` (its `info` keys are
    listed there)."""

    def __init__(
        self,
        simulator: Simulator,
        robot: Robot,
        task_config: TaskConfig | None = None,
        objectives: Sequence[Objective] = (),
        *,
        seed: int = 0,
        device: str | torch.device | None = None,
    ):
        self.sim = simulator
        self.robot = robot
        self.cfg = task_config or TaskConfig()
        self.objectives = list(objectives)
        self.device = torch.device(device if device is not None else simulator.device)
        self.generator = torch.Generator(device=self.device)
        self.generator.manual_seed(int(seed))
        self.num_envs = simulator.num_envs
        self.num_actions = simulator.num_joints
        self.dt = simulator.control_dt
        self.max_episode_length = int(math.ceil(self.cfg.episode_seconds / self.dt))
        space = robot.design_space_for(simulator.designs[0])
        self.design_inputs = DesignInputs(robot, space.lower, space.upper, self.device)
        self.commands = CommandSampler(self.cfg.commands, self.device, self.generator)
        self.fixed_commands = False
        # paired evaluation: the scenario set's shared streams (`use_scenarios`), or None
        self.scenarios: SharedStreams | None = None
        self._paired_gen = torch.Generator(device=self.device)
        self._tick = 0  # policy steps since the last full `reset` (keys the paired noise)
        resample = self.cfg.commands.resample_seconds
        self.resample_steps = int(round(resample / self.dt)) if resample > 0 else 0

        simulator.set_gain_law(
            self.cfg.gain_law
        )  # "nominal" rebuilds the designs with the nominal gains
        state = simulator.reset()
        self.num_legs = int(state.foot_pos.shape[1])
        legs = robot.legs()
        if len(legs) != self.num_legs:
            raise ValueError(
                f"robot '{robot.name}' declares {len(legs)} legs "
                f"but its model has {self.num_legs} feet"
            )
        # the gait clock's per-leg offsets (a trotting quadruped moves diagonal pairs together)
        offsets = torch.tensor([float(leg.phase_offset) for leg in legs], device=self.device)
        self.policy_layout = layout.policy_layout(self.num_actions, self.cfg.history)
        self.critic_layout = self.policy_layout + layout.privileged_layout(self.num_legs)
        self.obs_slices = layout.slices(self.policy_layout)
        self.num_obs = layout.size(self.policy_layout)
        self.num_critic_obs = layout.size(self.critic_layout)
        self.num_design_obs = space.dim
        self.num_metrics = len(self.objectives)
        # wall seconds spent inside the simulator and in the whole `step` (throughput split)
        self.timing = {"physics": 0.0, "step": 0.0}

        n, j, legs = self.num_envs, self.num_actions, self.num_legs
        z = lambda *shape: torch.zeros(*shape, device=self.device)  # noqa: E731
        self.command = z(n, 3)  # [N, 3]
        self.gait = GaitClock(self.cfg.gait, offsets, n, self.dt, self.device)
        self.episode_length = torch.zeros(n, dtype=torch.long, device=self.device)
        self.action_history = z(n, self.cfg.history, j)  # [N, H, J] newest first
        self.last_joint_vel = z(n, j)
        self.last_contact = torch.zeros(n, legs, dtype=torch.bool, device=self.device)
        self.standing_height = z(n)
        self.episode_sums = episodes.new_sums(n, self.device)  # [ROWS, N]
        # the binding motor speed limit: the actuation's no torque beyond the no-load speed, and
        # how long each environment has had a joint beyond it without a break (s)
        self.sim.set_speed_limit(self.cfg.motor_speed_limit)
        self.design_inputs.track_speed_limit = self.cfg.motor_speed_limit == "binding"
        self.overspeed_time = z(n)
        self._refresh_design_buffers()
        self._restart(torch.arange(n, device=self.device), state)

    # -- sizes and designs ----------------------------------------------------------------
    @property
    def metric_names(self) -> list[str]:
        return [o.name for o in self.objectives]

    def _to_device(self, state: SimState) -> SimState:
        return state if state.base_pos.device == self.device else state.to(self.device)

    def _refresh_design_buffers(self) -> None:
        d = self.design_inputs
        d.refresh(self.sim)
        self.design_obs = normalize_designs(self.sim.designs, d.low, d.high)  # [N, D]
        self.designs, self.total_mass = d.designs, d.total_mass
        self.default_joint_pos, self.default_feet = d.default_joint_pos, d.default_feet
        aware = self.cfg.gait.design_aware
        self.gait.rescale(self.default_feet, d.nominal_leg_length if aware else 1.0)

    def set_designs(self, env_ids: torch.Tensor | np.ndarray, designs: np.ndarray) -> None:
        """Rebuild the given environments for new designs [len(env_ids), D] (they restart)."""
        ids = torch.as_tensor(np.asarray(env_ids), dtype=torch.long, device=self.device)
        self.sim.set_designs(ids.cpu().numpy(), np.asarray(designs, dtype=float))
        self._refresh_design_buffers()
        self._restart(ids, self.sim.get_state())

    def set_commands(self, commands: torch.Tensor | None) -> None:
        """Hold fixed commands [N, 3] (evaluation), or None to sample them again."""
        if commands is None:
            self.fixed_commands = False
            return
        self.fixed_commands = True
        self.command[:] = torch.as_tensor(commands, dtype=torch.float32, device=self.device).expand(
            self.num_envs, 3
        )
        self._freeze_clock(torch.arange(self.num_envs, device=self.device))

    # -- episode bookkeeping ----------------------------------------------------------------
    @property
    def phase(self) -> torch.Tensor:
        """[N] each environment's gait phase in [0, 1) (`GaitClock`)."""
        return self.gait.phase

    def _freeze_clock(self, ids: torch.Tensor) -> None:
        """Environments `ids` with a zero command wait at mid-stance of the first leg."""
        if self.cfg.gait.freeze_on_zero_command:
            still = self.command[ids].abs().sum(dim=-1) == 0
            self.gait.phase[ids[still]] = 0.25

    def _start(self, ids: torch.Tensor, state: SimState) -> None:
        """Per-env buffers of environments that (re)start an episode."""
        if ids.numel() == 0:
            return
        self.episode_length[ids] = 0
        self.action_history[ids] = 0.0
        self.last_joint_vel[ids] = state.joint_vel[ids].float()
        self.gait.air_time[ids] = 0.0
        self.overspeed_time[ids] = 0.0
        self.last_contact[ids] = state.foot_contact[ids]
        self.standing_height[ids] = (state.base_pos[ids, 2] - state.terrain_height[ids]).float()
        self.episode_sums[:, ids] = 0.0
        if self.scenarios is not None:  # paired: agent i always starts at its own phase
            self.gait.phase[ids] = self.scenarios.phase[ids % self.scenarios.phase.numel()]
        else:
            draw = torch.rand(ids.numel(), generator=self.generator, device=self.device)
            self.gait.phase[ids] = draw
        if not self.fixed_commands:
            self.command[ids] = self.commands.sample(ids.numel())
        self._freeze_clock(ids)

    def reset(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Reset every environment: (obs, critic_obs, design_obs)."""
        self._tick = 0
        state = self._restart(torch.arange(self.num_envs, device=self.device), self.sim.reset())
        obs, critic = self._observe(state)
        return obs, critic, self.design_obs

    def _restart(self, ids: torch.Tensor, state: SimState) -> SimState:
        """Start episodes of environments `ids` from the simulator's `state` (all of it
        new after a reset or a change of designs); the state on this device, held."""
        state = self._to_device(state)
        # the randomized parameters' part of the critic state [N, 8] (friction, restitution, PD
        # factor, motor strength, delay, CoM shift): read at each reset, not at every step (they
        # change only when an environment restarts), a gather and a cast on the sim's device
        self._param_obs = self.sim.env_params.privileged(self.device)
        self._start(ids, state)
        self.state = state
        return state

    # -- observations -----------------------------------------------------------------------
    def _noise(self, shape: tuple[int, ...], scale: float) -> torch.Tensor:
        gen = self._paired_gen if self.scenarios is not None else self.generator
        if self.cfg.noise.kind == "gaussian":
            return scale * self.paired_draw(shape, gen)
        return scale * (2.0 * self.paired_draw(shape, gen, normal=False) - 1.0)

    def _observe(self, state: SimState) -> tuple[torch.Tensor, torch.Tensor]:
        """(noisy policy obs [N, num_obs], critic state [N, num_critic_obs])."""
        lin, ang, gravity = state.base_frame()
        joint_pos = state.joint_pos.float() - self.default_joint_pos
        joint_vel = state.joint_vel.float()
        clock = self.gait.features()
        clean = torch.cat(
            [
                lin,
                ang,
                gravity,
                self.command,
                joint_pos,
                joint_vel,
                self.action_history.flatten(1),
                clock,
            ],
            dim=-1,
        )
        obs = clean
        noise = self.cfg.noise
        if noise.enabled:
            if self.scenarios is not None:  # the same noise however often this step is observed
                key = np.random.SeedSequence([self.scenarios.seed, self._tick]).generate_state(
                    2, dtype=np.uint64
                )
                self._paired_gen.manual_seed(int(key[0] >> np.uint64(1)))
            n, s = self.num_envs, self.obs_slices
            obs = clean.clone()
            obs[:, s["base_lin_vel"]] += self._noise((n, 3), noise.base_lin_vel)
            obs[:, s["base_ang_vel"]] += self._noise((n, 3), noise.base_ang_vel)
            obs[:, s["projected_gravity"]] += self._noise((n, 3), noise.projected_gravity)
            obs[:, s["joint_pos"]] += self._noise((n, self.num_actions), noise.joint_pos)
            obs[:, s["joint_vel"]] += self._noise((n, self.num_actions), noise.joint_vel)
        terrain = state.terrain_height.float()
        privileged = torch.cat(
            [
                (state.base_pos[:, 2].float() - terrain)[:, None],
                state.foot_contact.float(),
                state.foot_pos[:, :, 2].float() - terrain[:, None],
                self._param_obs,
            ],
            dim=-1,
        )
        return obs, torch.cat([clean, privileged], dim=-1)

    # -- stepping ---------------------------------------------------------------------------
    def raibert_joint_targets(
        self, command: torch.Tensor, lin_vel: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(q* [N, J], expected stance [N, L]) of the paper's Raibert reference at this step."""
        return self.gait.reference(self.robot, self.designs, self.default_feet, command, lin_vel)

    def step(self, actions: torch.Tensor) -> StepResult:
        start = time.perf_counter()
        result = self._step(actions)
        self.timing["step"] += time.perf_counter() - start
        return result

    def _step(self, actions: torch.Tensor) -> StepResult:
        cfg = self.cfg
        actions = actions.to(self.device).float().clamp(-cfg.action_clip, cfg.action_clip)  # [N, J]
        targets = (
            self.default_joint_pos + cfg.action_scale * actions
        )  # [N, J] joint position targets
        sim_device = torch.device(self.sim.device)
        tick = time.perf_counter()
        state = self._to_device(self.sim.step(targets.to(sim_device)))
        self.timing["physics"] += time.perf_counter() - tick
        self.episode_length += 1
        self._tick += 1

        moving = self.command.abs().sum(dim=-1) > 0  # [N]
        self.gait.advance(moving)

        lin, ang, gravity = state.base_frame()
        joint_vel = state.joint_vel.float()
        contact = state.foot_contact
        height, terminated, timeout = self._termination(state, gravity)
        frame = (lin, ang, gravity)
        inputs = self._reward_inputs(state, frame, actions, joint_vel, moving, terminated)
        terms = compute_terms(inputs, cfg.rewards)
        reward, weighted = combine(terms, cfg.rewards, self.dt)
        metrics = self._metrics(
            StepBatch(
                command=self.command,
                base_lin_vel=lin,
                base_ang_vel=ang,
                joint_torque=inputs.joint_torque,
                joint_vel=joint_vel,
                joint_targets=targets,
                design=self.designs,
                total_mass=self.total_mass,
                base_height=height,
                foot_contact=contact,
                dt=self.dt,
            )
        )
        self._record_step(
            actions, joint_vel, contact, terms.get("tracking_lin_vel"), reward, moving, lin
        )

        obs, critic = self._observe(state)
        done = terminated | timeout
        info: dict = {
            "metrics": metrics,
            "final_critic_obs": critic,
            "terminated": terminated,
            "base_lin_vel": lin,
            "base_ang_vel": ang,
            "foot_contact": contact,
            "half_stance": half_stance(contact),
            "command": self.command.clone(),
            "reward_terms": {k: v.mean() for k, v in weighted.items()},  # 0-dim tensors, no sync
        }
        state, changed = self._end_episodes(done, terminated, info, state, sim_device)
        self.state = state
        if changed:  # observe the restarted environments (and new commands) afresh
            obs, critic = self._observe(state)
        return StepResult(obs, critic, self.design_obs, reward, done, timeout, info)

    def _reward_inputs(
        self,
        state: SimState,
        frame: tuple[torch.Tensor, torch.Tensor, torch.Tensor],
        actions: torch.Tensor,
        joint_vel: torch.Tensor,
        moving: torch.Tensor,
        terminated: torch.Tensor,
    ) -> RewardInputs:
        """What the reward terms read of this step (`state` after it and its `base_frame`,
        the clipped `actions`, float joint velocities, which commands move, which
        environments ended in a fall)."""
        lin, ang, gravity = frame
        contact = state.foot_contact
        first_contact, air_time = self.gait.touch_down(contact)
        q_star, stance = self.raibert_joint_targets(self.command, lin)
        return RewardInputs(
            command=self.command,
            base_lin_vel=lin,
            base_ang_vel=ang,
            projected_gravity=gravity,
            joint_pos=state.joint_pos.float(),
            default_joint_pos=self.default_joint_pos,
            joint_acc=(joint_vel - self.last_joint_vel) / self.dt,
            joint_torque=state.joint_torque.float(),
            action=actions,
            last_action=self.action_history[:, 0],
            raibert_targets=q_star,
            foot_contact=contact,
            expected_stance=stance,
            first_contact=first_contact,
            air_time=air_time,
            moving_command=moving,
            terminated=terminated,
        )

    def _termination(
        self, state: SimState, gravity: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(base height over the terrain [N], terminated [N]: fell or diverged, timeout [N])."""
        cfg = self.cfg
        height = state.base_pos[:, 2].float() - state.terrain_height.float()
        fell = (height < cfg.min_base_height * self.standing_height) | (
            gravity[:, 2] > -cfg.max_tilt_cos
        )
        if cfg.motor_speed_limit == "binding":  # a joint beyond its no-load speed too long: a fall
            over = (state.joint_vel.float().abs() > self.design_inputs.speed_limit).any(dim=-1)
            self.overspeed_time = torch.where(
                over, self.overspeed_time + self.dt, torch.zeros_like(self.overspeed_time)
            )
            fell = fell | (self.overspeed_time >= cfg.overspeed_seconds - 1e-6)
        terminated = fell | state.diverged.to(self.device)
        timeout = (self.episode_length >= self.max_episode_length) & ~terminated
        return height, terminated, timeout

    def _metrics(self, step_batch: StepBatch) -> torch.Tensor:
        """[N, M] the objectives' per-step costs."""
        if self.objectives:
            return torch.stack(
                [o.step_cost(step_batch).float() for o in self.objectives], dim=-1
            )  # [N, M]
        return torch.zeros(self.num_envs, 0, device=self.device)

    def _record_step(self, actions, joint_vel, contact, tracking, reward, moving, lin) -> None:
        """Bookkeeping for the next observation and the episodes' statistics."""
        self.action_history = torch.roll(self.action_history, 1, dims=1)
        self.action_history[:, 0] = actions
        self.last_joint_vel = joint_vel
        self.last_contact = contact
        episodes.add_step(
            self.episode_sums, reward, tracking, moving, lin[:, 0], self.command[:, 0]
        )

    def _end_episodes(
        self, done, terminated, info: dict, state: SimState, sim_device
    ) -> tuple[SimState, bool]:
        """Restart the environments that ended (their episodes' statistics into
        `info["episode"]`) and give new commands to those due one. One host synchronisation:
        which environments ended, which are due a new command, and the sums of the ended
        episodes' statistics travel together. Returns the state and whether any changed."""
        resample = self.resample_steps and not self.fixed_commands
        if resample:  # environments that end now restart at length 0: never due
            due = ~done & (self.episode_length % self.resample_steps == 0)
        else:
            due = torch.zeros_like(done)
        ended = done.float()
        lengths = self.episode_length.float()  # >= 1 after this step
        sums = episodes.over_ended(self.episode_sums, ended, terminated, lengths)
        host = torch.cat([ended, due.float(), sums]).cpu().numpy()
        n = self.num_envs
        done_ids = np.flatnonzero(host[:n])
        due_ids = np.flatnonzero(host[n : 2 * n])
        changed = done_ids.size > 0
        if changed:
            ended_now = episodes.ended_episodes(host[2 * n :].tolist(), int(done_ids.size), self.dt)
            info["episode"] = ended_now.report
            if not self.fixed_commands:
                self.commands.record_episodes(
                    ended_now.count,
                    int(round(ended_now.falls)),
                    ended_now.moving_tracking,
                    ended_now.moving_steps,
                    ended_now.seconds,
                )
            cpu_ids = torch.from_numpy(done_ids)
            tick = time.perf_counter()
            fresh = self.sim.reset(cpu_ids.to(sim_device))
            self.timing["physics"] += time.perf_counter() - tick
            state = self._restart(cpu_ids.to(self.device), fresh)
        if due_ids.size > 0:
            due_ids = torch.from_numpy(due_ids).to(self.device)
            self.command[due_ids] = self.commands.sample(due_ids.numel())
            self._freeze_clock(due_ids)
            changed = True
        return state, changed
