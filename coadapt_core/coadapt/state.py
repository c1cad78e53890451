"""The co-adaptation loop's state and its persistence: `LoopState` (everything a run needs
to continue), written into the run folder after every training phase and every evaluation
batch as data only (`state.json`, the evaluation buffer as `buffer-<n>.npz`, the optimizer
as its `state_dict()`; never a pickle), read back by `load_state` on `--resume`, with the
checks a resumed run makes before it writes anything (same starting policy, a writable
folder). The state's own bookkeeping of the costs seen (best, top candidates) lives here too.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core import surrogate_quality as sq
from coadapt_core.errors import UserError
from coadapt_core.optimizer import Optimizer
from coadapt_core.statefile import StateFileError, read_json, read_npz, write_json, write_npz

STATE_FILE = "state.json"
BUFFER_FILE_STEM = "buffer"  # <run_dir>/buffer-<serial>.npz: the evaluation buffer R_eval
LEGACY_STATE_FILE = "state.pkl"  # written by coadapt before state files were data only; never read
STATE_FORMAT = "coadapt-loop-state-1"


@dataclass
class RoundRecord:
    """One optimizer round's evaluation as `CoadaptationLoop.evaluate` returns it and the loop
    records it (`LoopState.add_batch`, the recorder's rows): costs [P, M] under the run's cost
    rule, what it spent, the surrogate's errors [P, M] (a real round whose prediction was
    judged) and what a real round measured; `uncertainty` is the ensemble's spread ratio when
    it chose the round's kind (the uncertainty policy), else None."""

    kind: str
    costs: np.ndarray
    interactions: int
    seconds: float
    surrogate_errors: np.ndarray | None = None
    survival: float | None = None  # mean survival of a real batch
    tracking_ratio: float | None = None  # mean tracking ratio of a real batch
    # best design's cost SE, median relative SE, fall rate
    error_bars: dict[str, Any] = field(default_factory=dict)
    uncertainty: float | None = None

    def per_design(self, names: list[str]) -> dict[str, Any]:
        """The round as the recorder's rows take it (`RunRecorder.record_evaluations`): each
        design's costs and surrogate errors by objective name, and its share of what the
        round spent (interactions stay integers that sum to the round's)."""
        n = len(self.costs)
        errors = self.surrogate_errors
        return {
            "costs": [dict(zip(names, map(float, row), strict=True)) for row in self.costs],
            "interactions": _shares(int(self.interactions), n),
            "seconds": _shares(float(self.seconds), n),
            "surrogate_errors": None
            if errors is None
            else [dict(zip(names, map(float, row), strict=True)) for row in errors],
        }

    def measured(self) -> dict[str, Any]:
        return {
            "survival": self.survival,
            "tracking_ratio": self.tracking_ratio,
            **self.error_bars,
            "uncertainty": self.uncertainty,
        }


def _shares(total: float, n: int) -> list[float]:
    """A round's total split evenly among its n designs (integers stay integers and sum
    exactly)."""
    if isinstance(total, int):
        base, rest = divmod(total, n)
        return [base + (1 if i < rest else 0) for i in range(n)]
    return [total / n] * n


@dataclass
class LoopState:
    """Everything needed to continue a run; written atomically to `<run_dir>/state.json`."""

    run_id: str
    config: dict[str, Any]
    phase: str = "train"  # train | optimize | refine | final | done
    outer: int = 0
    inner: int = 0
    space: dict | None = None  # current design range (DesignSpace.to_dict)
    train_designs: np.ndarray | None = None  # [K, dim] designs of this outer iteration
    optimizer: Optimizer | None = None
    optimizer_init: dict[str, Any] | None = None  # the optimizer's constructor arguments (data)
    optimizer_state: dict[str, Any] | None = None  # its state_dict(), until the loop rebuilds it
    buffer: Any = None  # evaluation buffer R_eval (written to its own file, see save_state)
    buffer_outer: int = -1  # outer iteration whose policy filled the buffer
    buffer_serial: int = -1  # bumped whenever the buffer is replaced
    buffer_saved_serial: int = -1  # the serial written to <run_dir>/buffer-<serial>.npz
    rng_state: dict | None = None  # numpy Generator of sampling and the hybrid switch
    torch_rng_state: Any = None
    backend_checkpoint: str | None = None  # relative to the run folder
    # a training phase cut into chunks (coadapt/phase.py): {"outer", "done" (interactions),
    # "chunk" (chunks done), "seconds"} after its last mid-phase checkpoint; None between phases
    train_progress: dict[str, Any] | None = None
    best_real: tuple[list[float], float] | None = None  # (design, cost) lowest real cost seen
    # lowest distinct real costs
    top_real: list[tuple[list[float], float]] = field(default_factory=list)
    best_any: tuple[list[float], float, str] | None = None  # lowest cost of any kind
    counters: dict[str, float] = field(
        default_factory=lambda: {
            "train_interactions": 0,
            "eval_interactions": 0,
            "final_interactions": 0,
            "train_seconds": 0.0,
            "eval_seconds": 0.0,
            "surrogate_seconds": 0.0,
            "final_seconds": 0.0,
            "real_evaluations": 0,
            "surrogate_evaluations": 0,
            "designs_evaluated": 0,
        }
    )
    batches: list[dict[str, Any]] = field(default_factory=list)  # one summary per evaluation batch
    # real rounds of the current policy, the labels the pseudo-critics are fitted to:
    # {"designs": [[...]], "costs": [[...]]} (issue 16, docs/coadaptation.md "The surrogate")
    labels: list[dict[str, Any]] = field(default_factory=list)
    # surrogate against real cost on each real round's designs (coadapt_core.surrogate_quality)
    quality_rounds: list[dict[str, Any]] = field(default_factory=list)
    spaces: list[dict] = field(default_factory=list)  # the range of each outer iteration
    # the cost rule's reference level [M] (`capped`: the nominal design's median scenario cost
    # under the policy of outer iteration `reference_outer`, on the run's scenario set)
    reference: list[float] | None = None
    reference_outer: int = -1
    elapsed: float = 0.0  # wall-clock seconds spent before the current process
    summary: dict[str, Any] | None = None
    policy: dict[str, Any] | None = None  # the starting policy's provenance
    # warnings printed at the start, kept in the summary
    notes: list[str] = field(default_factory=list)
    # objectives without a pseudo-critic in the starting policy
    no_critic: list[str] = field(default_factory=list)
    # the refinement stage after the search (coadapt/refine.py): its optimizer's constructor
    # arguments and state_dict() as data, its steps, whether it finished; None: not started
    refine: dict[str, Any] | None = None

    def note_costs(self, designs: np.ndarray, costs: np.ndarray, kind: str, keep: int) -> None:
        """The lowest cost of any kind and the lowest real costs seen, from a batch's designs
        [P, dim] and first-objective costs [P] (non-finite costs are skipped)."""
        for design, cost in zip(designs, costs, strict=True):
            if not np.isfinite(cost):
                continue
            if self.best_any is None or cost < self.best_any[1]:
                self.best_any = (design.tolist(), float(cost), kind)
            if kind == "real" and (self.best_real is None or cost < self.best_real[1]):
                self.best_real = (design.tolist(), float(cost))
            if kind == "real":
                self.keep_top(design, float(cost), keep)

    def add_batch(self, record: RoundRecord) -> None:
        """One entry of `batches` (summary.json): the round's costs [P, M] summarised, the
        surrogate's mean absolute error [P, M] on a real round, and what the round measured
        (survival, tracking, error bars, the ensemble's spread)."""
        kind, costs, errors = record.kind, record.costs, record.surrogate_errors
        interactions, seconds = int(record.interactions), float(record.seconds)
        finite = np.isfinite(costs[:, 0])
        error_finite = None if errors is None else np.isfinite(errors[:, 0])
        self.batches.append(
            {
                "outer": self.outer,
                "inner": self.inner,
                "kind": kind,
                "designs": len(costs),
                "interactions": interactions,
                "seconds": seconds,
                "best_cost": float(costs[finite, 0].min()) if finite.any() else None,
                "mean_cost": float(costs[finite, 0].mean()) if finite.any() else None,
                # a diverged pseudo-critic gives NaN/inf: counted, and told to the optimizer
                # as the worst cost
                "nonfinite_costs": int((~finite).sum()),
                "surrogate_abs_error": float(np.abs(errors[error_finite, 0]).mean())
                if errors is not None and error_finite.any()
                else None,
                **record.measured(),
            }
        )
        self.note_ceiling(record)

    def note_ceiling(self, record: RoundRecord) -> None:
        """A judged real round's noise ceiling (`surrogate_quality.noise_ceiling`: the
        Spearman its designs' cost SEs allow; the paired SEs, as its designs ran on common
        scenarios) beside the surrogate's Spearman on it, in its `quality_rounds` entry (first
        objective; the SEs kept as `se`)."""
        # the paired SE where the round has one (designs on common scenarios), else its own
        se = record.error_bars.get("cost_paired_se") or record.error_bars.get("cost_se")
        q = self.quality_rounds[-1] if self.quality_rounds else None
        if record.kind != "real" or se is None or q is None or not q.get("objectives"):
            return
        if (q["outer"], q["inner"]) != (self.outer, self.inner):
            return
        first = next(iter(q["objectives"]))
        entry = q["objectives"][first]
        q["objectives"][first] = {**sq.with_ceiling(entry, entry["real"], se), "se": se}

    def keep_top(self, design: np.ndarray, cost: float, keep: int) -> None:
        """The `keep` (`final_candidates`) lowest real costs over distinct designs (a noisy
        evaluation flatters the luckiest design; the final check re-evaluates several)."""
        top = self.top_real
        for i, (other, other_cost) in enumerate(top):
            if np.allclose(other, design):
                if cost < other_cost:
                    top[i] = (design.tolist(), cost)
                break
        else:
            top.append((design.tolist(), cost))
        top.sort(key=lambda item: item[1])
        del top[keep:]


_RECOVER = (
    "; the run cannot continue from it: start it again with `coadapt run` (same options) "
    "in a new --out"
)
_NOT_SAVED = ("optimizer", "optimizer_state", "buffer")


def save_state(run_dir: Path, state: LoopState) -> None:
    """Write the state atomically as JSON (arrays inline). The evaluation buffer can be large
    (every state of a real round), so it goes to its own `.npz`, written only when it changed
    (`buffer_serial`). The optimizer is saved as its `state_dict()`."""
    if "torch" in sys.modules:  # the learner's RNG; never import torch just for this
        state.torch_rng_state = sys.modules["torch"].get_rng_state()
    buffer = state.buffer
    stale = None
    if state.phase == "done" and state.buffer_saved_serial >= 0:
        # a finished run is resumed from its summary alone: the buffer (tens of MB for a
        # quick run) is kept only while the run can still continue
        stale = run_dir / f"{BUFFER_FILE_STEM}-{state.buffer_saved_serial}.npz"
        state.buffer_saved_serial = -1
    elif buffer is not None and state.buffer_saved_serial != state.buffer_serial:
        write_npz(run_dir / f"{BUFFER_FILE_STEM}-{state.buffer_serial}.npz", buffer)
        stale = run_dir / f"{BUFFER_FILE_STEM}-{state.buffer_saved_serial}.npz"
        state.buffer_saved_serial = state.buffer_serial
    data = {"format": STATE_FORMAT}
    for f in fields(LoopState):
        if f.name not in _NOT_SAVED:
            data[f.name] = getattr(state, f.name)
    data["optimizer_state"] = (
        state.optimizer.state_dict() if state.optimizer is not None else state.optimizer_state
    )
    write_json(run_dir / STATE_FILE, data)
    if stale is not None and stale.exists():  # only once the new state points past it
        stale.unlink()


def load_state(run_dir: Path) -> LoopState:
    """The state `save_state` wrote (the optimizer still as data: `optimizer_state`, rebuilt
    by the loop). A damaged or foreign file is a one-line `UserError` naming it."""
    path = run_dir / STATE_FILE
    if not path.is_file():
        if (run_dir / LEGACY_STATE_FILE).is_file():
            raise UserError(
                f"cannot resume: '{run_dir}' holds a {LEGACY_STATE_FILE} from an older "
                "coadapt; pickled state is never read (it can run code): start the run again",
                field="resume",
            )
        raise UserError(
            f"cannot resume: '{run_dir}' has no {STATE_FILE} (not a run folder, or it never "
            "started)",
            field="resume",
        )
    data = read_json(path, what="run state", recover=_RECOVER)
    names = {f.name for f in fields(LoopState)}
    if (
        not isinstance(data, dict)
        or data.get("format") != STATE_FORMAT
        or not {"run_id", "config"} <= set(data)
    ):
        raise StateFileError(
            f"run state '{path}' is not a coadapt run state{_RECOVER}", field="resume"
        )
    try:
        state = LoopState(
            **{k: v for k, v in data.items() if k in names and k not in ("optimizer", "buffer")}
        )
        _check_state(state)
    except (TypeError, ValueError) as exc:
        raise StateFileError(
            f"run state '{path}' is damaged ({type(exc).__name__}: {exc}){_RECOVER}", field="resume"
        ) from None
    if state.buffer_saved_serial >= 0:
        buffer_path = run_dir / f"{BUFFER_FILE_STEM}-{state.buffer_saved_serial}.npz"
        if not buffer_path.is_file():
            raise StateFileError(
                f"evaluation buffer '{buffer_path}' is missing{_RECOVER}", field="resume"
            )
        from coadapt_core.plugins import get_registry

        # every plugin's classes: their modules register the buffer types they save
        get_registry().load_all()  # (statefile.register_dataclass)
        state.buffer = read_npz(buffer_path, what="evaluation buffer", recover=_RECOVER)
    if state.torch_rng_state is not None:
        import torch

        torch.set_rng_state(state.torch_rng_state)
    return state


def _check_state(state: LoopState) -> None:
    """Types that the loop relies on (a hand-edited or foreign file fails here, in one line)."""
    if not isinstance(state.run_id, str) or not isinstance(state.config, dict):
        raise ValueError("run_id or config has the wrong type")
    if state.phase not in ("train", "optimize", "refine", "final", "done"):
        raise ValueError(f"unknown phase {state.phase!r}")
    for name in ("outer", "inner", "buffer_serial", "buffer_saved_serial"):
        if not isinstance(getattr(state, name), int):
            raise ValueError(f"{name} is not an integer")
    if state.backend_checkpoint is not None:
        rel = Path(str(state.backend_checkpoint))
        if rel.is_absolute() or ".." in rel.parts:
            raise ValueError("backend checkpoint path leaves the run folder")
    progress = state.train_progress
    if progress is not None and not (
        isinstance(progress, dict)
        and isinstance(progress.get("done"), int)
        and isinstance(progress.get("chunk"), int)
        and progress.get("outer") == state.outer
    ):
        raise ValueError("train_progress is not this outer iteration's chunk count")
    for name in ("best_real", "best_any"):
        if getattr(state, name) is not None:
            setattr(state, name, tuple(getattr(state, name)))
    state.top_real = [tuple(item) for item in state.top_real]
    torch_rng = state.torch_rng_state
    if torch_rng is not None and type(torch_rng).__name__ != "Tensor":
        raise ValueError("torch RNG state is not a tensor")


def check_same_policy(state: LoopState, policy: dict[str, Any] | None) -> None:
    """A resumed run starts from the policy file it started from: a file whose SHA-256
    changed since (a reinstalled plugin shipping a retrained policy, an overwritten path) is
    refused in one line. A run recorded before provenance existed takes today's."""
    recorded = (state.policy or {}).get("sha256")
    if policy is None or not recorded or state.phase == "done":
        state.policy = state.policy or policy
        return
    if policy.get("sha256") != recorded:
        now = policy.get("sha256")
        now_text = now[:12] + "..." if now else "no file"
        raise UserError(
            f"cannot resume run {state.run_id}: its starting policy {state.policy.get('path')} "
            f"changed since the run started (SHA-256 {recorded[:12]}... then, {now_text} now); "
            "restore that file, or start a new run",
            field="resume",
        )


def check_writable(run_path: Path, state: LoopState) -> None:
    """A resumed run writes its folder: one that cannot be written is one line here, before
    the store or a logger thread (TensorBoard's) touches it."""
    probe = run_path / f".{state.run_id}.write-check"
    try:
        with open(probe, "wb"):
            pass
        probe.unlink()
    except OSError as exc:
        raise UserError(
            f"cannot resume: run folder '{run_path}' cannot be written "
            f"({exc.strerror or type(exc).__name__}); make it writable, or copy it to a folder "
            "you can write and resume the copy",
            field="resume",
        ) from None
