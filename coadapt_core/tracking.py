"""Experiment tracking: TensorBoard event files (the default) or Weights & Biases, for
`coadapt train` and `coadapt run`. The trainer and the loop only call `on_training_iteration`
and a logger's `log_*` methods; which backend writes them is chosen here (`--logger`)."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from coadapt_core.errors import UserError

LOGGERS = ("tensorboard", "wandb", "none")


class ExperimentLogger:
    """Scalars by tag and step. The base class logs nothing (`--logger none`)."""

    kind = "none"

    def __init__(self) -> None:
        self.train_step = 0  # interactions trained so far in this command (x axis of train/*)

    def _write(self, tag: str, value: float, step: int) -> None:
        pass

    def log_scalar(self, tag: str, value: Any, step: int) -> None:
        try:
            value = float(value)
        except (TypeError, ValueError):
            return
        if math.isfinite(value):
            self._write(tag, value, int(step))

    def log_scalars(self, prefix: str, values: Mapping[str, Any], step: int) -> None:
        for key, value in values.items():
            if isinstance(value, Mapping):
                self.log_scalars(f"{prefix}/{key}", value, step)
            elif isinstance(value, int | float) and not isinstance(value, bool):
                self.log_scalar(f"{prefix}/{key}", value, step)

    def flush(self) -> None:
        pass

    def close(self) -> None:
        pass


class TensorBoardLogger(ExperimentLogger):
    """Event files under `log_dir` (`tensorboard --logdir <run folder>/tb`)."""

    kind = "tensorboard"

    def __init__(self, log_dir: str | Path):
        super().__init__()
        try:
            from torch.utils.tensorboard import SummaryWriter
        except ImportError:  # tensorboard is a dependency; a trimmed environment may lack it
            raise UserError(
                "--logger tensorboard needs the tensorboard package: pip install tensorboard "
                "(or --logger none)",
                field="logger",
            ) from None
        self.log_dir = Path(log_dir)
        self.writer = SummaryWriter(log_dir=str(self.log_dir))

    def _write(self, tag: str, value: float, step: int) -> None:
        self.writer.add_scalar(tag, value, step)

    def flush(self) -> None:
        self.writer.flush()

    def close(self) -> None:
        self.writer.close()


class WandbLogger(ExperimentLogger):
    """A Weights & Biases run (project `coadapt`, or $WANDB_PROJECT); offline unless the
    user logged in (`WANDB_MODE` decides, as wandb documents)."""

    kind = "wandb"

    def __init__(self, log_dir: str | Path, *, name: str, config: Mapping[str, Any] | None = None):
        super().__init__()
        import os

        import wandb

        Path(log_dir).mkdir(parents=True, exist_ok=True)
        self.run = wandb.init(
            project=os.environ.get("WANDB_PROJECT", "coadapt"),
            name=name,
            dir=str(log_dir),
            config=dict(config or {}),
            reinit=True,
        )

    def _write(self, tag: str, value: float, step: int) -> None:
        self.run.log({tag: value, "step": step})

    def close(self) -> None:
        self.run.finish()


def check_logger(kind: str) -> str:
    """The logger name, or a `UserError` (exit 2) for an unknown one or a missing wandb."""
    if kind not in LOGGERS:
        raise UserError(f"--logger '{kind}' is not one of {', '.join(LOGGERS)}", field="logger")
    if kind == "wandb":
        import importlib.util

        if importlib.util.find_spec("wandb") is None:
            raise UserError(
                "--logger wandb needs wandb, which is not installed: pip install wandb "
                "(or --logger tensorboard)",
                field="logger",
            )
    return kind


def tensorboard_installed() -> bool:
    """Whether torch's TensorBoard writer can be used (the `tensorboard` package is there)."""
    import importlib.util

    return importlib.util.find_spec("tensorboard") is not None


def make_logger(
    kind: str,
    log_dir: str | Path,
    *,
    name: str = "coadapt",
    config: Mapping[str, Any] | None = None,
) -> ExperimentLogger:
    """The logger `kind` writing under `log_dir`. TensorBoard (the default) where its package
    is not installed (a trimmed environment, the GPU machine's wheels): no logger, said in one
    line on stderr, and the command runs on; a missing wandb, asked for by name, is an error."""
    kind = check_logger(kind)
    if kind == "tensorboard" and not tensorboard_installed():
        import sys

        print(
            "note: tensorboard is not installed: no event files are written "
            "(pip install tensorboard; --logger none says this is meant)",
            file=sys.stderr,
        )
        return ExperimentLogger()
    if kind == "tensorboard":
        return TensorBoardLogger(log_dir)
    if kind == "wandb":
        return WandbLogger(log_dir, name=name, config=config)
    return ExperimentLogger()


# -- the hook the trainer calls -----------------------------------------------------------------
_active: list[ExperimentLogger] = []


@contextlib.contextmanager
def active(logger: ExperimentLogger | None) -> Iterator[ExperimentLogger | None]:
    """While active, every training iteration (any trainer in this process) is logged to it."""
    if logger is None:
        yield None
        return
    _active.append(logger)
    try:
        yield logger
    finally:
        _active.remove(logger)


def log_values(prefix: str, values: Mapping[str, Any], step: int) -> None:
    """`prefix/<name>` scalars at `step` to every active logger (the loop's surrogate
    quality per real round: `surrogate_quality/<objective>_<figure>`)."""
    for logger in _active:
        logger.log_scalars(prefix, values, step)


def on_training_iteration(stats: Any, samples: int) -> None:
    """Called by the trainer after each PPO iteration: `train/<stat>` at the interactions
    trained so far in this command (phases of a co-adaptation run follow one another)."""
    if not _active:
        return
    values = stats.to_dict() if hasattr(stats, "to_dict") else dict(stats)
    for logger in _active:
        logger.train_step += int(samples)
        logger.log_scalars(
            "train", {k: v for k, v in values.items() if k not in ("iteration",)}, logger.train_step
        )


__all__ = [
    "LOGGERS",
    "ExperimentLogger",
    "active",
    "check_logger",
    "log_values",
    "make_logger",
    "on_training_iteration",
]


# -- the co-adaptation loop -----------------------------------------------------------------
class TrackingRecorder:
    """Wraps a run's recorder: everything is recorded as before, and each training phase,
    optimizer round (best cost so far per objective, the round's kind) and surrogate error
    also goes to the logger (`phase/*`, `round/*`, `surrogate/*`, `final/*`)."""

    def __init__(self, inner: Any, logger: ExperimentLogger):
        self.inner = inner
        self.logger = logger
        self.phases = 0
        self.rounds = 0
        self.best_real: dict[str, float] = {}

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)

    def record_training(self, run_id: str, *, outer: int, result: Any) -> None:
        self.inner.record_training(run_id, outer=outer, result=result)
        self.phases += 1
        self.logger.log_scalars(
            "phase",
            {
                "outer": outer,
                "steps": result.steps,
                "seconds": result.seconds,
                "mean_reward": result.mean_reward,
                **dict(result.extra or {}),
            },
            self.phases,
        )
        self.logger.flush()

    def record_evaluations(self, run_id: str, **batch: Any) -> None:
        self.inner.record_evaluations(run_id, **batch)
        self._log_round(batch["costs"], batch["kind"], batch.get("surrogate_errors"))

    def _log_round(
        self, costs: list[dict[str, float]], kind: str, errors: list[dict[str, float]] | None
    ) -> None:
        self.rounds += 1
        values: dict[str, float] = {"surrogate_round": float(kind == "surrogate")}
        for name in costs[0] if costs else ():
            finite = [c[name] for c in costs if math.isfinite(c.get(name, math.nan))]
            if not finite:
                continue
            values[f"batch_best_{name}"] = min(finite)
            if kind == "real":
                self.best_real[name] = min(self.best_real.get(name, math.inf), min(finite))
            if name in self.best_real:
                values[f"best_real_{name}"] = self.best_real[name]
        self.logger.log_scalars("round", values, self.rounds)
        if errors:
            quality: dict[str, float] = {}
            for name in errors[0]:
                pairs = [
                    (e[name], c[name])
                    for e, c in zip(errors, costs, strict=False)
                    if math.isfinite(e.get(name, math.nan))
                    and math.isfinite(c.get(name, math.nan))
                    and c[name] != 0
                ]
                if pairs:
                    quality[f"abs_error_{name}"] = sum(abs(e) for e, _ in pairs) / len(pairs)
                    quality[f"rel_error_{name}"] = sum(abs(e) / abs(c) for e, c in pairs) / len(
                        pairs
                    )
            self.logger.log_scalars("surrogate", quality, self.rounds)
        self.logger.flush()

    def finish(self, run_id: str, summary: dict[str, Any], status: str = "finished") -> None:
        self.inner.finish(run_id, summary, status)
        self.log_final(summary)

    def log_final(self, summary: dict[str, Any]) -> None:
        """The run's final figures (`final/*`), without recording the run as finished."""
        final = {
            k: summary[k]
            for k in ("best_cost", "nominal_cost", "improvement", "interactions", "seconds")
            if isinstance(summary.get(k), int | float)
        }
        if final:
            self.logger.log_scalars("final", final, 0)
        self.logger.flush()
