"""PPO for the universal policy with a critic and pseudo-critics, on TorchRL's `ClipPPOLoss`
and `GAE`, split the rsl_rl way: `act`, `process_env_step`, `compute_returns`, `update`.

The pseudo-critics (paper section 3.2.2), their targets and what the surrogate reads of
them live in `coadapt_core.learning.pseudo_critics`.
"""

from __future__ import annotations

import copy
import time
from dataclasses import dataclass

import torch
from tensordict import TensorDict
from tensordict.nn import TensorDictModule

from coadapt_core.learning.config import TrainConfig, resolve_precision
from coadapt_core.learning.networks import (
    ActorNet,
    CriticBank,
    EmpiricalNormalization,
    MeanActor,
    ValueNet,
)
from coadapt_core.learning.pseudo_critics import (
    PseudoCritics,
    all_finite,
    discounted_average_targets,
    new_pseudo_critics,
)

#: per-step metrics are clamped to +-METRIC_LIMIT before the pseudo-critics see them
METRIC_LIMIT = 1e15


@dataclass
class Dims:
    num_obs: int  # policy observation o (70)
    num_critic_obs: int  # critic state s
    num_design: int  # xi
    num_actions: int  # 8
    num_metrics: int  # M objectives / pseudo-critics


class PPO:
    """The learner. Attributes:

    actor_net: pi(a | o, xi) mean MLP + log-std; critic_net: V(s, xi);
    pseudo_critic: V_pseudo(s, xi), a `CriticBank` of one MLP per objective computed as one
    batched ensemble (None when M = 0);
    obs_norm / critic_norm: running normalisers of o and s; pseudo_norm: of the per-step metrics
    (the pseudo-critics' target scale);
    loss: TorchRL ClipPPOLoss over actor + critic; gae: TorchRL GAE;
    optimizer: Adam over actor + critic; pseudo_optimizer: Adam over the pseudo-critics only.
    """

    def __init__(self, dims: Dims, config: TrainConfig, device: str | torch.device = "cpu"):
        from torchrl.modules import IndependentNormal, ProbabilisticActor, ValueOperator
        from torchrl.objectives import ClipPPOLoss
        from torchrl.objectives.value import GAE

        self.dims = dims
        self.config = config
        self.device = torch.device(device)
        c = config
        self.actor_net = ActorNet(
            dims.num_obs,
            dims.num_design,
            dims.num_actions,
            c.hidden,
            c.activation,
            c.init_noise_std,
        ).to(self.device)
        self.critic_net = ValueNet(dims.num_critic_obs, dims.num_design, c.hidden, c.activation).to(
            self.device
        )
        self.obs_norm = EmpiricalNormalization(dims.num_obs).to(self.device)
        self.critic_norm = EmpiricalNormalization(dims.num_critic_obs).to(self.device)
        self.pseudo_critic, self.pseudo_norm, self.pseudo_optimizer = new_pseudo_critics(
            dims.num_critic_obs, dims.num_design, dims.num_metrics, config, self.device
        )

        self.actor = ProbabilisticActor(
            TensorDictModule(
                self.actor_net, in_keys=["obs", "design_obs"], out_keys=["loc", "scale"]
            ),
            in_keys=["loc", "scale"],
            distribution_class=IndependentNormal,
            return_log_prob=True,
        )
        self.critic = ValueOperator(self.critic_net, in_keys=["critic_obs", "design_obs"])
        self.loss = ClipPPOLoss(
            self.actor,
            self.critic,
            clip_epsilon=c.clip_param,
            entropy_coeff=c.entropy_coef,
            critic_coeff=c.value_loss_coef,
            loss_critic_type="l2",
            normalize_advantage=True,
            # a logged statistic nothing here reads: one more reduction per minibatch
            log_explained_variance=False,
            functional=False,
        )
        self.gae = GAE(gamma=c.gamma, lmbda=c.lam, value_network=self.critic)
        self.learning_rate = c.learning_rate
        # foreach: the per-tensor Adam loop costs ~50x more on CPU for these sizes
        self.optimizer = torch.optim.Adam(self.loss.parameters(), lr=c.learning_rate, foreach=True)
        self.transitions: list[TensorDict] = []  # one [N] TensorDict per rollout step
        self.rollout: TensorDict | None = None  # [N, T] after compute_returns
        self.training = True
        #: `freeze_policy`: only the pseudo-critics learn (the rest stays exactly as it is);
        #: `pseudo_paused`: all but them (no targets, no regression; `coadapt train --until-walks`)
        self.policy_frozen = self.pseudo_paused = False
        #: wall seconds of compute_returns ("returns") and update ("update") and of the
        #: pseudo-critics' part of both ("pseudo"); `profile` makes them exact on a GPU
        self.timing = {"returns": 0.0, "update": 0.0, "pseudo": 0.0}
        self.profile = False
        self.mirror = None  # `symmetry.MirrorMaps` under TrainConfig.symmetry (the trainer's)
        self.update_rows = 0  # rows the PPO loss saw in the last update (mirror images too)
        #: numerics in force ("float32" | "bf16"), `TrainConfig.precision` / `pseudo_precision`
        #: resolved for this device
        self.precision = resolve_precision(c.precision, self.device)
        self.pseudo_precision = resolve_precision(c.pseudo_precision, self.device)

    # -- acting -----------------------------------------------------------------------------
    @torch.no_grad()
    def act(
        self, obs: torch.Tensor, critic_obs: torch.Tensor, design_obs: torch.Tensor
    ) -> torch.Tensor:
        """Sample actions [N, A] for a rollout step and start its transition record."""
        from torchrl.modules import IndependentNormal

        if self.training and not self.policy_frozen:
            self.obs_norm.update(obs)
            self.critic_norm.update(critic_obs)
        normed = self.obs_norm(obs)
        # what `self.actor` does under ExplorationType.RANDOM (a sample of its distribution and
        # its log-probability), without the module dispatch: about 1.5 ms of every rollout
        # step on a CPU; tests/core/test_learning_ppo.py checks the two agree to the bit
        loc, scale = self.actor_net(normed, design_obs)
        dist = IndependentNormal(loc, scale)  # the actor's distribution_class
        action = dist.rsample()
        td = TensorDict(
            {
                "obs": normed,
                "critic_obs": self.critic_norm(critic_obs),
                "design_obs": design_obs,
                "loc": loc,
                "scale": scale,
                "action": action,
                self.loss.tensor_keys.sample_log_prob: dist.log_prob(action),
            },
            batch_size=[obs.shape[0]],
            device=self.device,
        )
        self.transitions.append(td)
        return action

    @torch.no_grad()
    def action_distribution(
        self, obs: torch.Tensor, design_obs: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """(mean, std) [N, A] of the Gaussian policy at raw observations `obs`; the
        normalisers stay as they are. The policy that `learning.evaluate.rollout` takes."""
        return self.actor_net(self.obs_norm(obs), design_obs)

    @torch.no_grad()
    def act_inference(self, obs: torch.Tensor, design_obs: torch.Tensor) -> torch.Tensor:
        """Deterministic actions [N, A] (the policy mean), for evaluation and deployment."""
        return self.action_distribution(obs, design_obs)[0]

    def mean_actor(self) -> MeanActor:
        """The policy mean as a module of its own (a copy, in eval mode): raw observations and
        normalised designs -> `act_inference`'s actions, the observation normaliser's current
        statistics held as constants. What a deployment exports."""
        return MeanActor(copy.deepcopy(self.actor_net.body), self.obs_norm)

    @torch.no_grad()
    def process_env_step(
        self,
        reward: torch.Tensor,  # [N]
        done: torch.Tensor,  # [N] bool
        timeout: torch.Tensor,  # [N] bool
        final_critic_obs: torch.Tensor,  # [N, C] critic state before auto-reset
        design_obs: torch.Tensor,  # [N, D]
        metrics: torch.Tensor,  # [N, M]
    ) -> None:
        """Complete the current transition with what the environment returned."""
        td = self.transitions[-1]
        terminated = done & ~timeout
        td["next"] = TensorDict(
            {
                "critic_obs": self.critic_norm(final_critic_obs),
                "design_obs": design_obs,
                "reward": reward[:, None].float(),
                "done": done[:, None],
                "terminated": terminated[:, None],
                "truncated": timeout[:, None],
            },
            batch_size=td.batch_size,
        )
        # a non-finite or absurd metric (an exploding w_t = exp(e^2) of a flailing robot) must
        # not poison the pseudo-critics' running statistics: NaN -> 0, clamp to +-1e15 so the
        # float32 variance (squares) stays finite
        td["metrics"] = torch.nan_to_num(metrics.float(), nan=0.0).clamp(
            -METRIC_LIMIT, METRIC_LIMIT
        )

    # -- returns ----------------------------------------------------------------------------
    def pseudo_values(
        self, critic_obs_normed: torch.Tensor, design_obs: torch.Tensor
    ) -> torch.Tensor:
        """[*, M] de-normalised pseudo-critic predictions (in units of the per-step metric)."""
        scale, offset = self.pseudo_scale()
        return self.pseudo_critic(critic_obs_normed, design_obs) * scale + offset

    def pseudo_scale(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(scale [M], offset [M]): a pseudo-critic's raw output times scale plus offset is
        in units of the per-step metric (the metric's running statistics, `pseudo_norm`)."""
        norm, m = self.pseudo_norm, self.dims.num_metrics
        return torch.sqrt(norm.var[:m] + norm.eps), norm.mean[:m]

    def pseudo_critics(self) -> PseudoCritics | None:
        """The pseudo-critics as the surrogate reads them (None without objectives)."""
        if self.pseudo_critic is None:
            return None
        scale, offset = self.pseudo_scale()
        return PseudoCritics(self.pseudo_critic, scale, offset)

    def normalize_critic_states(self, critic_obs: torch.Tensor) -> torch.Tensor:
        """Raw critic states [n, C] as the critics read them, on the learner's device."""
        return self.critic_norm(critic_obs.to(self.device))

    @torch.no_grad()
    def compute_returns(self) -> TensorDict:
        """Stack the rollout to [N, T]; GAE advantages and value targets (TorchRL), and the
        pseudo-critic targets (module docstring)."""
        td = torch.stack(self.transitions, dim=1)  # [N, T]
        self.transitions = []
        begin = self._clock()
        if not self.policy_frozen:
            self.gae(td)
        if self.pseudo_critic is not None and not self.pseudo_paused:
            tick = self._clock()
            with self._autocast(self.pseudo_precision):  # the regression's numerics
                value_next = self.pseudo_values(
                    td["next", "critic_obs"], td["next", "design_obs"]
                ).float()  # [N, T, M]
            m = self.dims.num_metrics
            metrics = td["metrics"]
            seen = metrics.reshape(-1, m)
            value_next = torch.clamp(value_next, min=seen.amin(dim=0), max=seen.amax(dim=0))
            target = discounted_average_targets(
                metrics, value_next, td["next", "done"], self.config.gamma, self.config.pseudo_lam
            )
            self.pseudo_norm.update(metrics)
            scale, offset = self.pseudo_scale()
            td["pseudo_target"] = (target - offset) / scale
            self.timing["pseudo"] += self._clock() - tick
        self.rollout = td
        self.timing["returns"] += self._clock() - begin
        return td

    # -- update -----------------------------------------------------------------------------
    def _autocast(self, precision: str):
        """bf16 autocast of forward passes where `precision` (`TrainConfig.precision` for the
        PPO loss, `pseudo_precision` for the pseudo-critic regression) asks for it; float32
        otherwise (a no-op context). Parameters, optimizer states and losses stay float32."""
        return torch.autocast(self.device.type, dtype=torch.bfloat16, enabled=precision == "bf16")

    def _clock(self) -> float:
        """Wall time for the section timings; with `profile` set on an accelerator, after
        waiting for the queued work (else only the launch would be timed)."""
        if self.profile and self.device.type == "cuda":
            torch.cuda.synchronize(self.device)
        return time.perf_counter()

    def _adapt_learning_rate(self, kl: float) -> None:
        """rsl_rl's rule on the (approximate) KL between behaviour and current policy."""
        if kl > 2.0 * self.config.desired_kl:
            self.learning_rate = max(1e-5, self.learning_rate / 1.5)
        elif 0.0 < kl < self.config.desired_kl / 2.0:
            self.learning_rate = min(1e-2, self.learning_rate * 1.5)
        for group in self.optimizer.param_groups:
            group["lr"] = self.learning_rate

    def _update_keys(self) -> list:
        """The rollout's entries the minibatches gather: the PPO loss's inputs but the next
        state's (GAE used them up), advantages, value targets, the pseudo-critics' targets."""
        keys = self.loss.tensor_keys
        wanted = [k for k in self.loss.in_keys if not (isinstance(k, tuple) and k[0] == "next")]
        wanted += [keys.advantage, keys.value_target, "critic_obs", "design_obs", "pseudo_target"]
        return list(dict.fromkeys(wanted))

    def update(self) -> dict[str, float]:
        """Epochs x minibatches of the clipped PPO loss (actor + critic) and, on the same
        minibatch but in its own optimizer, of the pseudo-critic regression. Returns mean
        losses and the learning rate.

        One host synchronisation per minibatch: the approximate KL (which sets the adaptive
        learning rate) and whether the pseudo-critic loss is finite travel together; the
        loss sums stay on the device until the end."""
        c = self.config
        # strict=False: a frozen policy's rollout has no advantages (GAE did not run)
        flat = self.rollout.select(*self._update_keys(), strict=False).reshape(-1)
        n = flat.shape[0]
        size = max(n // c.minibatches, 1)
        keys = ("loss_objective", "loss_critic", "loss_entropy", "entropy")
        sums = torch.zeros(len(keys) + 1, device=self.device)  # + kl
        pseudo_sum = torch.zeros((), device=self.device)
        count = pseudo_count = 0
        params = list(self.loss.parameters())
        pseudo_params = [] if self.pseudo_critic is None else list(self.pseudo_critic.parameters())
        pseudo_epochs = 0 if self.pseudo_paused else (c.pseudo_epochs or c.epochs)
        pseudo_seconds, begin = 0.0, self._clock()
        frozen = self.policy_frozen
        images = None if self.mirror is None or frozen else self.mirror.image(flat)
        for epoch in range(pseudo_epochs if frozen else c.epochs):
            # one gather per epoch (`index_select` per entry: a third of `flat[order]`'s time),
            # the minibatches its slices (views): the same rows as gathering each on its own
            order = torch.randperm(n, device=self.device)
            take = lambda x, order=order: x.index_select(0, order)  # noqa: E731
            shuffled, mirrored = flat.apply(take), None if images is None else images.apply(take)
            for start in range(0, n - size + 1, size):
                batch = shuffled[start : start + size]
                if frozen:
                    out = dict.fromkeys((*keys, "kl_approx"), torch.zeros((), device=self.device))
                else:
                    with self._autocast(self.precision):
                        out = self.loss(batch)
                        if mirrored is not None:  # and its mirror image (`symmetry`)
                            out = self.mirror.joined(out, self.loss(mirrored[start : start + size]))
                    loss = out["loss_objective"] + out["loss_critic"] + out["loss_entropy"]
                pseudo = self.pseudo_critic is not None and epoch < pseudo_epochs
                flags = [out["kl_approx"].detach().float().reshape(())]
                if pseudo:
                    tick = self._clock()
                    # the pseudo-critics see data only: no path from their loss to the actor
                    with self._autocast(self.pseudo_precision):
                        pred = self.pseudo_critic(batch["critic_obs"], batch["design_obs"])
                    loss_pseudo = torch.nn.functional.mse_loss(pred.float(), batch["pseudo_target"])
                    flags.append(torch.isfinite(loss_pseudo).float())
                    pseudo_seconds += self._clock() - tick
                host = torch.stack(flags).tolist()  # the one synchronisation
                if c.schedule == "adaptive" and not frozen:
                    self._adapt_learning_rate(host[0])
                if not frozen:
                    self.optimizer.zero_grad(set_to_none=True)
                    loss.backward()
                    torch.nn.utils.clip_grad_norm_(params, c.max_grad_norm, foreach=True)
                    self.optimizer.step()
                if pseudo and host[1] > 0:  # never step on a non-finite loss
                    tick = self._clock()
                    self.pseudo_optimizer.zero_grad(set_to_none=True)
                    loss_pseudo.backward()
                    torch.nn.utils.clip_grad_norm_(pseudo_params, c.max_grad_norm, foreach=True)
                    self.pseudo_optimizer.step()
                    pseudo_sum += loss_pseudo.detach()
                    pseudo_count += 1
                    pseudo_seconds += self._clock() - tick
                sums += torch.stack(
                    [out[k].detach().float().reshape(()) for k in keys] + [flags[0]]
                )
                count += 1
        self.timing["update"] += self._clock() - begin
        self.timing["pseudo"] += pseudo_seconds
        self.rollout = None
        self.update_rows = 0 if frozen else count * size * (1 if images is None else 2)
        values = (sums / max(count, 1)).tolist()
        stats = dict(zip((*keys, "kl"), values, strict=True))
        stats["loss_pseudo"] = float(pseudo_sum) / max(pseudo_count, 1)
        stats["learning_rate"] = self.learning_rate
        stats["action_std"] = self.actor_net.log_std.detach().exp().mean().item()
        return stats

    # -- state ------------------------------------------------------------------------------
    def state_dict(self) -> dict:
        return {
            "actor": self.actor_net.state_dict(),
            "critic": self.critic_net.state_dict(),
            "pseudo_critic": self.pseudo_critic.state_dict() if self.pseudo_critic else None,
            "obs_norm": self.obs_norm.state_dict(),
            "critic_norm": self.critic_norm.state_dict(),
            "pseudo_norm": self.pseudo_norm.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "pseudo_optimizer": self.pseudo_optimizer and self.pseudo_optimizer.state_dict(),
            "learning_rate": self.learning_rate,
        }

    def load_state_dict(self, state: dict, *, optimizers: bool = True) -> None:
        self.actor_net.load_state_dict(state["actor"])
        self.critic_net.load_state_dict(state["critic"])
        if self.pseudo_critic is not None and state.get("pseudo_critic") is not None:
            # checkpoints of the per-head layout (before the bank was batched) are converted
            self.pseudo_critic.load_state_dict(
                CriticBank.convert_state_dict(state["pseudo_critic"])
            )
        self.obs_norm.load_state_dict(state["obs_norm"])
        self.critic_norm.load_state_dict(state["critic_norm"])
        self.pseudo_norm.load_state_dict(state["pseudo_norm"])
        # pseudo-critics poisoned by non-finite metrics (checkpoints written before the w_t
        # exponent was capped) predict NaN forever: they restart from scratch instead
        self.pseudo_reset = self.pseudo_critic is not None and not all_finite(
            self.pseudo_critic, self.pseudo_norm
        )
        if self.pseudo_reset:
            self.reset_pseudo_critics()
        if optimizers and "optimizer" in state:
            self.optimizer.load_state_dict(state["optimizer"])
            if (
                self.pseudo_optimizer is not None
                and state.get("pseudo_optimizer") is not None
                and not self.pseudo_reset
            ):
                bank = self.pseudo_critic
                saved = CriticBank.convert_optimizer_state(
                    state["pseudo_optimizer"], bank.num_heads, bank.num_layers
                )
                if saved is not None:
                    self.pseudo_optimizer.load_state_dict(saved)
        if "learning_rate" in state:
            # the KL-adapted rate the training had reached (weights exports carry it too), where
            # resuming or fine-tuning continues
            self.learning_rate = float(state["learning_rate"])
            for group in self.optimizer.param_groups:
                group["lr"] = self.learning_rate

    def load_actor(self, state: dict) -> None:
        """Load only the acting part of a `state_dict()` (the actor and the observation
        normaliser) and put it in eval mode: the policy for inference; the critics,
        pseudo-critics and optimizers stay as they are."""
        self.actor_net.load_state_dict(state["actor"])
        self.obs_norm.load_state_dict(state["obs_norm"])
        self.actor_net.eval()
        self.obs_norm.eval()

    def freeze_policy(self) -> None:
        """Train only the pseudo-critics from now on: refit the surrogate of a finished policy
        (or give it a new objective) without changing how it acts."""
        if self.pseudo_critic is None:
            raise ValueError("no pseudo-critics to train: the policy has no objectives")
        self.policy_frozen, self.pseudo_paused = True, False

    def reset_pseudo_critics(self) -> None:
        """Restart the pseudo-critics, their target normaliser and optimizer from scratch."""
        d = self.dims
        self.pseudo_critic, self.pseudo_norm, self.pseudo_optimizer = new_pseudo_critics(
            d.num_critic_obs, d.num_design, d.num_metrics, self.config, self.device
        )
