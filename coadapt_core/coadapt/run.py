"""Start or resume a co-adaptation run (`run_coadaptation`): the run folder, its first
state, the results store's rows, the run's TensorBoard/wandb logger, then the loop
(`loop.CoadaptationLoop`) to its summary. A resumed run is checked first (the folder can be
written, the starting policy is the file it started from) and a store that lost the run's
rows gets them back from the run folder before anything new is recorded."""

from __future__ import annotations

import contextlib
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core import threads
from coadapt_core.coadapt.config import CoadaptConfig
from coadapt_core.coadapt.config_loading import config_from_dict
from coadapt_core.coadapt.loop import CoadaptationLoop, ProgressFn
from coadapt_core.coadapt.setup import LoopParts, build_parts
from coadapt_core.coadapt.state import (
    STATE_FILE,
    LoopState,
    check_same_policy,
    check_writable,
    load_state,
    save_state,
)
from coadapt_core.coadapt.summary import CoadaptResult
from coadapt_core.design_space import DesignSpace
from coadapt_core.errors import UserError
from coadapt_core.fitness import CoadaptationBackend, RunRecorder
from coadapt_core.objective import Objective
from coadapt_core.optimizer import Optimizer
from coadapt_core.results.recorders import make_recorder
from coadapt_core.results.rows import new_run_id


def run_coadaptation(
    config: CoadaptConfig | None = None,
    *,
    backend_factory: Callable[[int], CoadaptationBackend] | None = None,
    design_space: DesignSpace | None = None,
    nominal_design: np.ndarray | None = None,
    objectives: Sequence[Objective] | None = None,
    optimizer_cls: type[Optimizer] | None = None,
    recorder: RunRecorder | None = None,
    resume: str | os.PathLike | None = None,
    run_dir: str | os.PathLike | None = None,
    progress: ProgressFn | None = None,
    on_start: Callable[[str, Path], None] | None = None,
    finishing: Callable[[CoadaptResult], None] | None = None,
) -> CoadaptResult:
    """Run (or resume) Algorithm 4 and return its summary.

    Anything not given is built from the registry and the config: the robot's design space
    (mixed for `mixed` or an optimizer that implies it) narrowed to `design_ranges`, its
    nominal design, the objectives, the optimizer class and the universal-policy backend. With
    `resume` (a run folder) the recorded config and state are used and `config` is ignored.

    `on_start(run_id, run_dir)` is called as soon as the run folder holds a state to resume
    from; `finishing(result)` after the final check and before the store says "finished"
    (the CLI renders its video there). An interrupt anywhere (Ctrl-C included) marks the run
    "interrupted" and propagates; `resume=run_dir` continues from the last state written.
    """
    given = dict(
        design_space=design_space,
        nominal_design=nominal_design,
        objectives=objectives,
        optimizer_cls=optimizer_cls,
        backend_factory=backend_factory,
    )
    if resume is not None:
        run_path = Path(resume).absolute()
        state = load_state(run_path)
        config = config_from_dict(state.config)
        check_writable(run_path, state)
    elif config is None:
        raise UserError("run_coadaptation needs a config or a run folder to resume", field="config")
    else:
        config.validate()
    parts = build_parts(config, **given)
    # the config as recorded (config.yaml, the store, the logger), its plugin options typed
    recorded = config.to_dict()
    if resume is not None:
        check_same_policy(state, parts.policy)
    else:
        run_path, state, recorder = _new_run(config, recorded, parts, run_dir, recorder)
    recorder = recorder or make_recorder(run_path, config.store or None)
    if on_start is not None:
        on_start(state.run_id, run_path)
    # `threads`: the budget this process gives the physics and torch (`coadapt_core.threads`), a
    # record like run_id, never read back (config.yaml keeps the first session's; each training
    # phase records the threads it ran on in trainings.jsonl)
    recorder.start_run(
        {
            **recorded,
            "run_id": state.run_id,
            "run_dir": str(run_path),
            "design_space": parts.full_space.to_dict(),
            "policy": state.policy,
            "threads": threads.budget(),
        }
    )
    run = _Run(config, recorded, state, parts, run_path, recorder)
    return _drive(run, progress, finishing, resumed=resume is not None)


def _new_run(
    config: CoadaptConfig,
    recorded: dict[str, Any],
    parts: LoopParts,
    run_dir: str | os.PathLike | None,
    recorder: RunRecorder | None,
) -> tuple[Path, LoopState, RunRecorder]:
    """A new run's folder, its first state (written before the store hears of the run) and
    its recorder."""
    run_id = (
        new_run_id(config.method, config.objective.split(","), config.seed, config.optimizer)
        if run_dir is None
        else Path(run_dir).name
    )
    run_path = (Path(run_dir) if run_dir is not None else Path(config.out) / run_id).absolute()
    if (run_path / STATE_FILE).exists():
        raise UserError(
            f"run folder '{run_path}' already holds a run; resume it or pick another", field="out"
        )
    run_path.mkdir(parents=True, exist_ok=True)
    recorder = recorder or make_recorder(
        run_path, config.store or None
    )  # a bad store: one line, nothing written
    state = LoopState(
        run_id=run_id,
        config=recorded,
        space=parts.space.to_dict(),
        policy=parts.policy,
        notes=list(parts.notes),
        no_critic=list(parts.no_critic),
    )
    for note in parts.notes:
        print(note, file=sys.stderr)
    # the state first, then the store's row: a run the store knows can always be resumed
    # (a grid killed in between used to leave a row "running" over a folder without one)
    save_state(run_path, state)
    return run_path, state, recorder


@dataclass
class _Run:
    """A started (or resumed) run as `_drive` takes it on: its config, as an object and as
    recorded, its state, its parts, its folder and its recorder."""

    config: CoadaptConfig
    recorded: dict[str, Any]
    state: LoopState
    parts: LoopParts
    path: Path
    recorder: RunRecorder


def _drive(
    run: _Run,
    progress: ProgressFn | None,
    finishing: Callable[[CoadaptResult], None] | None,
    *,
    resumed: bool,
) -> CoadaptResult:
    """The loop from the run's state to the store's "finished" (or "interrupted",
    re-raising)."""
    state, recorder = run.state, run.recorder
    try:
        if resumed:
            # a store that lost this run's rows (emptied, replaced, an old copy) gets them back
            # from the run folder's JSON lines before anything new is recorded
            refill = getattr(recorder, "refill_from_run_folder", None)
            if refill is not None:
                refill(state.run_id, run.path)
        if state.phase == "done":  # resuming a finished run (or one stopped in `finishing`)
            assert state.summary is not None
            summary = state.summary
        else:
            summary = _continue(run, progress)
        result = CoadaptResult(state.run_id, run.path, summary)
        _draw_figures(run.path, summary, run.recorded)
        if finishing is not None:
            finishing(result)
    except BaseException as exc:
        # the last state stays in the run folder; `resume=run_dir` continues from it. A failure
        # to record that (a folder gone read-only) must not hide what stopped the run.
        with contextlib.suppress(Exception):
            recorder.finish(
                state.run_id,
                {
                    "run_id": state.run_id,
                    "error": f"{type(exc).__name__}: {exc}",
                    "outer": state.outer,
                    "inner": state.inner,
                    "phase": state.phase,
                },
                "interrupted",
            )
        raise
    recorder.finish(state.run_id, summary, "finished")
    return result


def _draw_figures(run_path: Path, summary: dict[str, Any], recorded: dict[str, Any]) -> None:
    """The run's figures in its folder (`analysis.run_figures`: convergence, the Pareto front,
    the surrogate's error), one line naming them; a figure that cannot be drawn is said in
    that line and leaves the run's result alone."""
    try:
        from coadapt_core.analysis.run_figures import write_run_figures

        written = write_run_figures(run_path, summary, recorded)
    except Exception as exc:  # matplotlib missing or a record it cannot draw: the result stands
        print(f"figures: not drawn ({type(exc).__name__}: {exc})", file=sys.stderr)
        return
    if written:
        print(f"figures: {', '.join(p.name for p, _ in written)} in {run_path}", file=sys.stderr)


def _continue(run: _Run, progress: ProgressFn | None) -> dict[str, Any]:
    """Run the loop from the run's state to its summary, with its TensorBoard/wandb logger."""
    from coadapt_core import tracking

    # TensorBoard (default) / wandb: training curves, best cost per round, surrogate error
    logger = tracking.make_logger(
        run.config.logger, run.path / "tb", name=run.state.run_id, config=run.recorded
    )
    recorder = tracking.TrackingRecorder(run.recorder, logger)
    parts = run.parts
    loop = CoadaptationLoop(
        run.config,
        method=parts.method,
        backend_factory=parts.backend_factory,
        design_space=parts.full_space,
        nominal_design=parts.nominal,
        objectives=parts.objectives,
        optimizer_cls=parts.optimizer_cls,
        run_dir=run.path,
        recorder=recorder,
        state=run.state,
        progress=progress,
        pretrained=parts.pretrained,
    )
    try:
        with tracking.active(logger):
            summary = loop.run()
            recorder.log_final(summary)
            return summary
    finally:
        logger.close()
