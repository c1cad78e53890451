"""The run's plan and how far along it is: how many outer iterations and optimizer rounds
a method runs, how many interactions each training phase takes, and from the state alone
the progress event and the time left (`CoadaptationLoop.emit`, `coadapt run`'s ETA).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from coadapt_core.coadapt.config import CoadaptConfig
from coadapt_core.coadapt.state import LoopState
from coadapt_core.methods import Method


@dataclass(frozen=True)
class Schedule:
    """What a method runs: `outer_count` outer iterations of `rounds_per_outer` optimizer
    rounds each, each outer iteration after a training phase of `training_steps(outer)`
    interactions (none without a shared policy)."""

    outer_count: int
    rounds_per_outer: int
    shared: bool  # one policy shared by the designs, trained up front (the method's backend)
    retrain: bool  # the shared policy trains again at every outer iteration
    pretrained: bool  # the run starts from a universal policy over the full range
    train_steps: int  # the first training phase's interactions
    retrain_steps: int  # every later phase's

    @classmethod
    def of(cls, config: CoadaptConfig, method: Method, *, pretrained: bool) -> Schedule:
        outer = 1 if not (method.retrain or method.narrow) else config.outer_iterations
        if method.rounds_setting is not None:
            rounds = int(getattr(config, method.rounds_setting))
        elif outer == 1 and config.outer_iterations > 1:  # no-retrain: N*J in one swarm
            rounds = config.outer_iterations * config.optimizer_iterations
        else:
            rounds = config.optimizer_iterations
        return cls(
            outer_count=outer,
            rounds_per_outer=rounds,
            shared=method.backend_kind.shared_policy,
            retrain=method.retrain,
            pretrained=pretrained,
            train_steps=config.train_steps,
            retrain_steps=config.retrain_steps,
        )

    def training_steps(self, outer: int) -> int:
        """The interactions of outer iteration `outer`'s training phase (Algorithm 4 line
        11): 0 without a shared policy, after the first phase when the method does not
        retrain, and for no-retrain starting from a universal policy over the full range
        (as the paper's: 0 training interactions in its Table 7)."""
        if not self.shared or (self.pretrained and not self.retrain):
            return 0
        if outer == 0:
            return self.train_steps
        return self.retrain_steps if self.retrain else 0

    def fraction_of_steps(self, state: LoopState) -> float:
        """The share of the run's steps done (a training phase and each round one step, the
        final check the last)."""
        training = 1 if self.shared else 0  # a training step per outer iteration
        total = self.outer_count * (self.rounds_per_outer + training) + 1
        done = state.outer * (self.rounds_per_outer + training)
        if state.phase in ("optimize", "refine"):  # refine: after the last one's rounds
            done += training + min(state.inner, self.rounds_per_outer)
        if state.phase in ("final", "done"):
            done = total - (1 if state.phase == "final" else 0)
        return min(done / total, 1.0)

    def eta_seconds(
        self,
        state: LoopState,
        population: int,
        objectives: int,
        real_share: Callable[[int, int], float],
    ) -> float | None:
        """Seconds left, from the wall clock this run has measured (the counters are part of
        the state, so this holds right after a resume): the training phases still to come at
        the measured seconds per training interaction; the rounds still to come at the
        measured seconds of a real round and of a surrogate round (each including the
        pseudo-critics' fits it triggered), `real_share(real rounds, surrogate rounds)` of
        them real (`HybridPolicy.real_share`); the final check at the measured rollout
        seconds per design, for its designs and one block. None until a training phase (when
        one is to come) and a real round have been timed. The video is not included."""
        s, cnt = state, state.counters
        if s.phase == "done":
            return 0.0
        real_rounds, real_wall = cnt.get("real_rounds_timed", 0), cnt.get("real_round_wall", 0.0)
        if real_rounds <= 0:
            return None
        per_real = real_wall / real_rounds
        surrogate_rounds = cnt.get("surrogate_rounds_timed", 0)
        per_surrogate = (
            cnt.get("surrogate_round_wall", 0.0) / surrogate_rounds
            if surrogate_rounds
            else 0.5 * per_real
        )
        # training phases still to come (this outer iteration's if it has not trained yet)
        first = s.outer if s.phase == "train" else s.outer + 1
        steps_left = sum(self.training_steps(outer) for outer in range(first, self.outer_count))
        train_wall, train_steps = cnt.get("train_wall", 0.0), cnt.get("train_steps_timed", 0)
        if steps_left and train_steps <= 0:
            return None
        seconds = steps_left * (train_wall / train_steps if train_steps else 0.0)
        if s.phase in ("train", "optimize"):
            rounds_left = self.rounds_per_outer * (self.outer_count - s.outer) - (
                s.inner if s.phase == "optimize" else 0
            )
            share = real_share(real_rounds, surrogate_rounds)
            seconds += rounds_left * (share * per_real + (1 - share) * per_surrogate)
        real = [b for b in s.batches if b.get("kind") == "real"]
        per_design = sum(b["seconds"] for b in real) / max(sum(b["designs"] for b in real), 1)
        designs = (len(s.top_real) + 2) if objectives == 1 else population + 1
        return float(seconds + per_design * designs)

    def progress_event(
        self, state: LoopState, phase: str, elapsed: float, eta: float | None, **extra: Any
    ) -> dict[str, Any]:
        """What a progress listener hears (`coadapt run`'s progress line): where the run is,
        its best costs, interactions, seconds and ETA, and `extra`."""
        s, c = state, state.counters
        # the share of the time, once the ETA is known; else the share of the steps
        fraction = (
            elapsed / (elapsed + eta)
            if eta is not None and elapsed + eta > 0
            else self.fraction_of_steps(s)
        )
        return {
            "phase": phase,
            "outer": s.outer,
            "outer_total": self.outer_count,
            "inner": s.inner,
            "inner_total": self.rounds_per_outer,
            "fraction": fraction,
            "best_cost": None if s.best_real is None else s.best_real[1],
            "best_any": None if s.best_any is None else s.best_any[1],
            "interactions": int(
                c["train_interactions"] + c["eval_interactions"] + c["final_interactions"]
            ),
            "elapsed": elapsed,
            "eta": eta,
            **extra,
        }
