"""The training runner: what turns a `Trainer` (Algorithm 1's PPO iterations) into a training
run, in the spirit of rsl_rl's `OnPolicyRunner`.

A `Runner` drives one trainer through a budget of environment interactions and owns what a
run needs around the iterations: where it starts (`resume`, `init_from`, the learning rate
given over the one a checkpoint reached), the cadence (iterations for a budget, a checkpoint
every `checkpoint_every` iterations), the logging (one JSON line per iteration in
`progress.jsonl`, the experiment tracker), the interruption (Ctrl-C stops after the iteration
under way and writes a checkpoint first) and the end (`model_final.pt` and the small
`policy.pt` export). `coadapt train`, the co-adaptation loop's retraining
(`UniversalPolicyBackend.train`), the benchmarks and the tests drive it:

    runner = Runner(trainer, out=Path("runs/train"), checkpoint_every=50)
    # interactions; TrainingInterrupted on Ctrl-C (catch_ctrl_c)
    runner.learn(1_000_000, callback=print)
    final, weights = runner.finish()

A runner without `out` writes nothing: `learn` is the trainer's iterations for the budget.
"""

from __future__ import annotations

import contextlib
import json
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from coadapt_core import phase_progress, tracking
from coadapt_core.errors import UserError
from coadapt_core.learning.iteration_stats import IterationStats
from coadapt_core.learning.trainer import Trainer


class TrainingInterrupted(Exception):
    """Ctrl-C stopped a run after the iteration under way; `checkpoint` holds that iteration."""

    def __init__(self, checkpoint: Path, iteration: int):
        super().__init__(f"interrupted after iteration {iteration}: {checkpoint}")
        self.checkpoint = checkpoint
        self.iteration = iteration


class Runner:
    """Drives `trainer` through budgets of interactions (see the module docstring).

    out: the run folder (checkpoints/, progress.jsonl, model_final.pt, policy.pt); None
    writes nothing. checkpoint_every: a checkpoint every this many iterations (0: none but
    the interrupted and the final one; default: the trainer's `checkpoint_every` when `out`
    is given). tracker: an experiment tracker (`coadapt_core.tracking.make_logger`), active
    while `learn` runs and closed by `finish`/`close`. catch_ctrl_c: the first Ctrl-C asks
    `learn` to stop at the end of the iteration under way (a checkpoint, then
    `TrainingInterrupted`); a second one stops at once."""

    def __init__(
        self,
        trainer: Trainer,
        out: Path | None = None,
        *,
        checkpoint_every: int | None = None,
        tracker: Any = None,
        catch_ctrl_c: bool = False,
    ):
        self.trainer = trainer
        self.out = None if out is None else Path(out)
        if checkpoint_every is None:
            checkpoint_every = int(trainer.config.checkpoint_every) if self.out is not None else 0
        self.checkpoint_every = checkpoint_every
        self.tracker = tracker
        self.catch_ctrl_c = catch_ctrl_c
        self._stop_requested = False

    # -- where the run starts ---------------------------------------------------------------
    def resume(self, path: Path) -> dict:
        """Continue the run checkpointed in `path`: networks, optimizers, normalisers,
        counters, command curriculum and design stream."""
        return self.trainer.load(path)

    def init_from(self, path: Path) -> int | None:
        """Start a new run from `path`'s weights and normalisers (fresh optimizer state, the
        training clock `train_seconds` at 0). A
        policy taking fewer design values than the trainer's space gets zero weights for the
        new ones: returns the number it took then (None when no widening was needed)."""
        state = self.trainer.load(path, optimizers=False, widen=True)
        self.trainer.train_seconds = 0.0  # a new run: its training clock starts now
        taken = int(state["dims"]["num_design"])
        return taken if taken < self.trainer.design_space.dim else None

    def set_learning_rate(self, rate: float) -> None:
        """Start from this learning rate (the KL-adapted schedule continues from it): it wins
        over the rate a resumed or initial checkpoint reached, in every optimizer group."""
        ppo = self.trainer.ppo
        ppo.learning_rate = rate
        for group in ppo.optimizer.param_groups:
            group["lr"] = rate

    def restrict(
        self, *, reset_pseudo_critics: bool = False, pseudo_critics_only: bool = False
    ) -> None:
        """Restart the pseudo-critics from scratch, and/or train only them (the policy, the
        critic and the observation normalisers stay exactly as loaded)."""
        ppo = self.trainer.ppo
        if reset_pseudo_critics and ppo.pseudo_critic is not None:
            ppo.reset_pseudo_critics()
        if pseudo_critics_only:
            if ppo.pseudo_critic is None:
                raise UserError(
                    "--pseudo-critics-only: no objectives, so no pseudo-critics to train "
                    "(see --objectives)",
                    field="pseudo_critics_only",
                )
            ppo.freeze_policy()

    # -- cadence ----------------------------------------------------------------------------
    def iterations_for(self, steps: int) -> int:
        """PPO iterations for a budget of `steps` interactions (at least one)."""
        return self.trainer.iterations_for(int(steps))

    def checkpoint(self) -> Path:
        """Write `out/checkpoints/model_<iteration>.pt` now."""
        return self.trainer.save(
            self._folder() / "checkpoints" / f"model_{self.trainer.iteration}.pt"
        )

    def learn(
        self, steps: int, callback: Callable[[IterationStats], None] | None = None
    ) -> IterationStats:
        """Train for `steps` interactions: `run(iterations_for(steps))`."""
        return self.run(self.iterations_for(steps), callback)

    def run(
        self, iterations: int, callback: Callable[[IterationStats], None] | None = None
    ) -> IterationStats | None:
        """Run `iterations` PPO iterations (0: none, the trainer untouched), recording each
        (progress.jsonl, the cadence's checkpoints) before `callback` sees it. Raises
        `TrainingInterrupted` after a Ctrl-C (with `catch_ctrl_c`), its checkpoint written."""
        progress = (self._folder() / "progress.jsonl").open("a") if self.out is not None else None
        start = (
            self.trainer.total_steps
        )  # this phase's interactions, told to its listeners (phase_progress)
        total = max(int(iterations), 0) * int(
            getattr(self.trainer, "samples_per_iteration", 0) or 0
        )

        def record(stats: IterationStats) -> None:
            phase_progress.report(self.trainer.total_steps - start, total)
            if progress is not None:
                progress.write(json.dumps(stats.to_dict()) + "\n")
                progress.flush()
            if self.checkpoint_every and stats.iteration % self.checkpoint_every == 0:
                self.checkpoint()
            if callback is not None:
                callback(stats)
            if self._stop_requested:  # Ctrl-C during this iteration: stop at its end
                raise _Stop

        try:
            if iterations <= 0:
                return None
            if self.tracker is not None:
                self.tracker.train_step = (
                    self.trainer.total_steps
                )  # a resumed run continues its curves
            with tracking.active(self.tracker), self._ctrl_c():
                return self.trainer.learn(iterations, record)
        except _Stop:
            raise TrainingInterrupted(self.checkpoint(), self.trainer.iteration) from None
        finally:
            if progress is not None:
                progress.close()

    # -- the end ----------------------------------------------------------------------------
    def finish(self) -> tuple[Path, Path]:
        """Write `out/model_final.pt` (the full checkpoint) and `out/policy.pt` (the weights
        export), then close the tracker and the trainer. Returns both paths."""
        if self.tracker is not None:
            self.tracker.close()
            self.tracker = None
        final = self.trainer.save(self._folder() / "model_final.pt")
        weights = self.trainer.export_weights(self._folder() / "policy.pt")
        self.close()
        return final, weights

    def close(self) -> None:
        """Close the tracker (if still open) and the trainer's simulator."""
        if self.tracker is not None:
            self.tracker.close()
            self.tracker = None
        self.trainer.close()

    def _folder(self) -> Path:
        if self.out is None:
            raise UserError(
                "this runner writes nothing: give it an output folder (out)", field="out"
            )
        self.out.mkdir(parents=True, exist_ok=True)
        return self.out

    @contextlib.contextmanager
    def _ctrl_c(self) -> Iterator[None]:
        """Within: the first Ctrl-C (SIGINT) asks `learn` to stop after the iteration under way;
        a second one interrupts at once. Off the main thread, or without `catch_ctrl_c`: nothing."""
        self._stop_requested = False
        if not self.catch_ctrl_c or threading.current_thread() is not threading.main_thread():
            yield
            return
        previous = signal.getsignal(signal.SIGINT)

        def handler(signum: int, frame: Any) -> None:
            if self._stop_requested:
                raise KeyboardInterrupt
            self._stop_requested = True
            print(
                "\nCtrl-C: stopping after this iteration and writing a checkpoint "
                "(Ctrl-C again: stop now, without one)",
                file=sys.stderr,
                flush=True,
            )

        signal.signal(signal.SIGINT, handler)
        try:
            yield
        finally:
            signal.signal(signal.SIGINT, previous)


class _Stop(Exception):
    """Raised inside the trainer's callback to end `learn` after a Ctrl-C."""


__all__ = ["Runner", "TrainingInterrupted"]
