"""Velocity commands (vx, vy, yaw rate) with a share of zeros and a curriculum on their
magnitude (shared/walking-notes.md remedy 6)."""

from __future__ import annotations

import torch

from coadapt_core.task.config import CommandConfig


class CommandSampler:
    """Draws commands [n, 3] from the current (curriculum-limited) box."""

    def __init__(
        self, config: CommandConfig, device: str | torch.device, generator: torch.Generator
    ):
        self.config = config
        self.device = torch.device(device)
        self.generator = generator
        # current half-width of the command box (same limit on |vx|, |vy| and |yaw|)
        self.limit = config.curriculum_start if config.curriculum else float("inf")
        # finished episodes gathered for the next curriculum decision
        self._window = {
            "episodes": 0,
            "falls": 0,
            "tracking": 0.0,
            "moving_steps": 0.0,
            "seconds": 0.0,
        }

    def ranges(self) -> list[tuple[float, float]]:
        """The current (vx, vy, yaw) ranges: the configured ones clipped to +-limit."""
        out = []
        for lo, hi in (self.config.vx_range, self.config.vy_range, self.config.yaw_range):
            out.append((max(lo, -self.limit), min(hi, self.limit)))
        return out

    def sample(self, n: int) -> torch.Tensor:
        """[n, 3] commands; |v_xy| below zero_threshold and a share zero_share become 0."""
        u = torch.rand(n, 3, generator=self.generator, device=self.device)
        cmd = torch.empty(n, 3, device=self.device)
        for j, (lo, hi) in enumerate(self.ranges()):
            cmd[:, j] = lo + (hi - lo) * u[:, j]
        small = cmd[:, :2].norm(dim=-1) < self.config.zero_threshold
        cmd[small, :2] = 0.0
        cmd[cmd[:, 2].abs() < self.config.zero_threshold, 2] = 0.0
        zero = torch.rand(n, generator=self.generator, device=self.device) < self.config.zero_share
        cmd[zero] = 0.0
        return cmd

    def stratified(self, n: int, generator: torch.Generator | None = None) -> torch.Tensor:
        """[n, 3] commands covering the current box evenly, for evaluation: agent i's vx is
        the midpoint of the i-th of n equal strata of the vx range (a fixed grid, the same for
        every seed); vy and the yaw rate take the midpoints of their own n strata in an order
        shuffled by `generator` (a Latin hypercube). The zero rules of `sample` follow: a
        planar command slower than zero_threshold becomes 0 and round(zero_share * n) further
        agents, those with the slowest commands, stand still."""
        n = int(n)
        mid = (torch.arange(n, dtype=torch.float32) + 0.5) / max(n, 1)  # [n] in (0, 1)
        gen = generator if generator is not None else torch.Generator().manual_seed(0)
        cmd = torch.empty(n, 3)
        for j, (lo, hi) in enumerate(self.ranges()):
            u = mid if j == 0 else mid[torch.randperm(n, generator=gen)]
            cmd[:, j] = lo + (hi - lo) * u
        small = cmd[:, :2].norm(dim=-1) < self.config.zero_threshold
        cmd[small, :2] = 0.0
        cmd[cmd[:, 2].abs() < self.config.zero_threshold, 2] = 0.0
        extra = int(round(self.config.zero_share * n))
        if extra > 0:
            speed = cmd.abs().sum(dim=-1)
            speed[speed == 0] = float("inf")  # already standing: not counted again
            order = torch.argsort(speed, stable=True)[:extra]
            cmd[order[torch.isfinite(speed[order])]] = 0.0
        return cmd.to(self.device)

    def record_episodes(
        self, episodes: int, falls: int, tracking_sum: float, moving_steps: float, seconds: float
    ) -> bool:
        """Add finished episodes (their count, falls, the sum of the unweighted tracking term
        over steps with a moving command, the number of such steps, and their total duration
        in s); once a window is full, decide on the curriculum. Returns True when it widened."""
        w = self._window
        w["episodes"] += episodes
        w["falls"] += falls
        w["tracking"] += tracking_sum
        w["moving_steps"] += moving_steps
        w["seconds"] = w.get("seconds", 0.0) + seconds
        if w["episodes"] < self.config.curriculum_window:
            return False
        fall_rate = w["falls"] / max(w["seconds"], 1e-9)  # falls per second of episode time
        fraction = w["tracking"] / w["moving_steps"] if w["moving_steps"] > 0 else 0.0
        self._window = {
            "episodes": 0,
            "falls": 0,
            "tracking": 0.0,
            "moving_steps": 0.0,
            "seconds": 0.0,
        }
        if fall_rate > self.config.curriculum_max_fall_rate:
            return False
        return self.update_curriculum(fraction)

    def update_curriculum(self, tracking_fraction: float) -> bool:
        """Widen the box when episodes tracked well (fraction of the maximum linear tracking
        reward); returns True when it widened."""
        if not self.config.curriculum or tracking_fraction < self.config.curriculum_threshold:
            return False
        widest = max(
            abs(v)
            for r in (self.config.vx_range, self.config.vy_range, self.config.yaw_range)
            for v in r
        )
        if self.limit >= widest:
            return False
        self.limit = min(self.limit + self.config.curriculum_step, widest)
        return True

    def state_dict(self) -> dict:
        """The curriculum: the box's half-width and the episodes gathered towards the next
        decision (a resumed run must widen the box when the uninterrupted one would)."""
        return {"limit": self.limit, "window": dict(self._window)}

    def load_state_dict(self, state: dict) -> None:
        self.limit = float(state["limit"])
        if "window" in state:  # checkpoints before the window was saved start a fresh one
            self._window = dict(state["window"])
