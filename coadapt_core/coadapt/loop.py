"""Algorithm 4, design co-adaptation, end to end: sample designs from the current range,
(re)train the universal policy and pseudo-critics on them, run the optimizer with hybrid
real/surrogate fitness, narrow the range around the final particles; finally re-evaluate the
best design and the nominal one for real.

One code path serves every method of the paper's comparison, each a row of the method
registry (`coadapt_core.methods`): its switches, and the kind of backend its designs
are evaluated with (the universal policy, or a policy per design for the BO baseline). The
loop's whole state is written into the run folder after every training phase and every
evaluation batch, as data only (`state.json`, the evaluation buffer as `buffer-<n>.npz`, the
optimizer as its `state_dict()`; never a pickle), so `run_coadaptation(..., resume=run_dir)`
continues where it stopped.
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core import surrogate_quality as sq
from coadapt_core.coadapt.config import CoadaptConfig, config_from_dict
from coadapt_core.coadapt.final_check import batch_errors, final_check, no_uncertainty
from coadapt_core.coadapt.reliability import fall_verdict, judge_short, walking
from coadapt_core.coadapt.setup import build_parts
from coadapt_core.design_space import DesignSpace
from coadapt_core.errors import UserError
from coadapt_core.fitness import (
    CoadaptationBackend,
    CostRule,
    RealFitness,
    RunRecorder,
    TrainingResult,
    scenario_seed,
)
from coadapt_core.methods import get_method
from coadapt_core.objective import Objective
from coadapt_core.optimizer import Optimizer
from coadapt_core.pareto import pareto_front
from coadapt_core.results.recorders import make_recorder
from coadapt_core.results.store import new_run_id
from coadapt_core.statefile import StateFileError, read_json, read_npz, write_json, write_npz

STATE_FILE = "state.json"
BUFFER_FILE_STEM = "buffer"  # <run_dir>/buffer-<serial>.npz: the evaluation buffer R_eval
LEGACY_STATE_FILE = "state.pkl"  # written by coadapt before state files were data only; never read
STATE_FORMAT = "coadapt-loop-state-1"


@dataclass
class LoopState:
    """Everything needed to continue a run; written atomically to `<run_dir>/state.json`."""

    run_id: str
    config: dict[str, Any]
    phase: str = "train"  # train | optimize | final | done
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
    best_real: tuple[list[float], float] | None = None  # (design, cost) lowest real cost seen
    top_real: list[tuple[list[float], float]] = field(default_factory=list)  # lowest distinct real costs
    best_any: tuple[list[float], float, str] | None = None  # lowest cost of any kind
    counters: dict[str, float] = field(default_factory=lambda: {
        "train_interactions": 0, "eval_interactions": 0, "final_interactions": 0,
        "train_seconds": 0.0, "eval_seconds": 0.0, "surrogate_seconds": 0.0, "final_seconds": 0.0,
        "real_evaluations": 0, "surrogate_evaluations": 0, "designs_evaluated": 0,
    })
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
    policy: dict[str, Any] | None = None  # the starting policy's provenance (setup.policy_provenance)
    notes: list[str] = field(default_factory=list)  # warnings printed at the start, kept in the summary
    no_critic: list[str] = field(default_factory=list)  # objectives without a pseudo-critic in the starting policy


#: the `--json` line's fields beside the rule's cost: the rule, the paper's plain mean (eq. 4)
#: with its standard error and improvement, fall rates with standard errors and their paired
#: difference, and whether the best design falls significantly more often than nominal
JSON_PLAIN_AND_FALLS = ("cost_rule", "best_plain_mean", "best_plain_mean_se", "nominal_plain_mean",
                        "nominal_plain_mean_se", "improvement_plain", "improvement_plain_se", "best_fall_rate_se",
                        "nominal_fall_rate_se", "fall_rate_difference", "fall_rate_difference_se", "falls_more")


@dataclass
class CoadaptResult:
    run_id: str
    run_dir: Path
    summary: dict[str, Any]

    def json_line(self) -> dict[str, Any]:
        s = self.summary
        line = {k: s.get(k) for k in ("run_id", "best_design", "best_cost", "best_cost_se", "nominal_cost", "nominal_cost_se",
                                 "improvement", "improvement_se", "significant", "best_fall_rate", "nominal_fall_rate",
                                 *JSON_PLAIN_AND_FALLS, "interactions", "seconds")}
        # the walking gate's verdict travels with every improvement (reliability.py)
        line["reliable"] = s.get("reliable")
        line["reliability"] = s.get("reliability")
        return line


ProgressFn = Callable[[dict[str, Any]], None]


# ------------------------------------------------------------------------------------------
_RECOVER = "; the run cannot continue from it: start it again with `coadapt run` (same options) in a new --out"
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
    data["optimizer_state"] = state.optimizer.state_dict() if state.optimizer is not None else state.optimizer_state
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
                f"cannot resume: '{run_dir}' holds a {LEGACY_STATE_FILE} from an older coadapt; pickled state is "
                "never read (it can run code): start the run again", field="resume")
        raise UserError(f"cannot resume: '{run_dir}' has no {STATE_FILE} (not a run folder, or it never started)", field="resume")
    data = read_json(path, what="run state", recover=_RECOVER)
    names = {f.name for f in fields(LoopState)}
    if not isinstance(data, dict) or data.get("format") != STATE_FORMAT or not {"run_id", "config"} <= set(data):
        raise StateFileError(f"run state '{path}' is not a coadapt run state{_RECOVER}", field="resume")
    try:
        state = LoopState(**{k: v for k, v in data.items() if k in names and k not in ("optimizer", "buffer")})
        _check_state(state)
    except (TypeError, ValueError) as exc:
        raise StateFileError(f"run state '{path}' is damaged ({type(exc).__name__}: {exc}){_RECOVER}", field="resume") from None
    if state.buffer_saved_serial >= 0:
        buffer_path = run_dir / f"{BUFFER_FILE_STEM}-{state.buffer_saved_serial}.npz"
        if not buffer_path.is_file():
            raise StateFileError(f"evaluation buffer '{buffer_path}' is missing{_RECOVER}", field="resume")
        from coadapt_core.plugins import get_registry

        get_registry()  # plugins register their buffer types (statefile.register_dataclass)
        state.buffer = read_npz(buffer_path, what="evaluation buffer", recover=_RECOVER)
    if state.torch_rng_state is not None:
        import torch

        torch.set_rng_state(state.torch_rng_state)
    return state


def _check_state(state: LoopState) -> None:
    """Types that the loop relies on (a hand-edited or foreign file fails here, in one line)."""
    if not isinstance(state.run_id, str) or not isinstance(state.config, dict):
        raise ValueError("run_id or config has the wrong type")
    if state.phase not in ("train", "optimize", "final", "done"):
        raise ValueError(f"unknown phase {state.phase!r}")
    for name in ("outer", "inner", "buffer_serial", "buffer_saved_serial"):
        if not isinstance(getattr(state, name), int):
            raise ValueError(f"{name} is not an integer")
    if state.backend_checkpoint is not None:
        rel = Path(str(state.backend_checkpoint))
        if rel.is_absolute() or ".." in rel.parts:
            raise ValueError("backend checkpoint path leaves the run folder")
    for name in ("best_real", "best_any"):
        if getattr(state, name) is not None:
            setattr(state, name, tuple(getattr(state, name)))
    state.top_real = [tuple(item) for item in state.top_real]
    torch_rng = state.torch_rng_state
    if torch_rng is not None and type(torch_rng).__name__ != "Tensor":
        raise ValueError("torch RNG state is not a tensor")


def quality_of(surrogate: list[float], real: list[float]) -> dict[str, Any]:
    return sq.clean({k: v for k, v in sq.quality(surrogate, real).items()})


def _floats(values: list[Any]) -> list[float]:
    """JSON lists with None (a non-finite value) as NaN."""
    return [float("nan") if v is None else float(v) for v in values]


def spread_ratio(members: np.ndarray) -> float:
    """The ensemble's disagreement on a round, members [E, K, M]: per objective, the mean
    over designs of the members' standard deviation over the standard deviation of the
    members' mean across the designs; the largest over objectives. Below 1 the members
    disagree less than the designs differ; infinite when the designs are predicted alike
    or a prediction is not finite."""
    members = np.asarray(members, dtype=float)
    if members.shape[0] < 2 or members.shape[1] < 2 or not np.isfinite(members).all():
        return float("inf")
    ratios = []
    for j in range(members.shape[2]):
        between = members[:, :, j].mean(axis=0).std()
        within = members[:, :, j].std(axis=0).mean()
        ratios.append(within / between if between > 0 else float("inf"))
    return float(max(ratios))


def _split(total: float, n: int) -> list[float]:
    """Share a batch's cost among its n designs (integers stay integers and sum exactly)."""
    if isinstance(total, int):
        base, rest = divmod(total, n)
        return [base + (1 if i < rest else 0) for i in range(n)]
    return [total / n] * n


# ------------------------------------------------------------------------------------------
class CoadaptationLoop:
    """Runs Algorithm 4 as a small state machine over `LoopState` (see module docstring)."""

    def __init__(
        self,
        config: CoadaptConfig,
        *,
        backend_factory: Callable[[int], CoadaptationBackend],
        design_space: DesignSpace,
        nominal_design: np.ndarray,
        objectives: Sequence[Objective],
        optimizer_cls: type[Optimizer],
        run_dir: Path,
        recorder: RunRecorder,
        state: LoopState,
        progress: ProgressFn | None = None,
        pretrained: bool = False,
    ):
        self.config = config
        self.pretrained = pretrained
        self.method = get_method(config.method)
        # the method's backend shares one policy between designs (universal) or not (a
        # policy per design: nothing to train up front, no surrogate, real costs are final)
        self.shared = self.method.backend_kind.shared_policy
        self.backend_factory = backend_factory
        self.full_space = design_space
        self.nominal = np.asarray(nominal_design, dtype=float)
        self.objectives = list(objectives)
        self.names = [o.name for o in self.objectives]
        self.optimizer_cls = optimizer_cls
        self.cost_rule = CostRule(config.cost_rule, config.cost_cap)
        self.run_dir = run_dir
        self.recorder = recorder
        self.state = state
        self.progress = progress
        self.rng = np.random.default_rng(config.seed)
        if state.rng_state is not None:
            self.rng.bit_generator.state = state.rng_state
        self.started = time.perf_counter()
        self.backend: CoadaptationBackend | None = None
        self._last_survival: float | None = None  # mean survival of the last real batch
        self._last_tracking: float | None = None  # mean tracking ratio of the last real batch
        self._last_errors: dict[str, Any] = {}  # error bars and fall rate of the last real batch
        self._fitted_for: tuple[int, int, int] | None = None  # (outer, labels, buffer) the backend's fit is for
        self._pending: tuple[int, np.ndarray] | None = None  # (inner, ensemble's costs) of a trusted round
        self._last_uncertainty: float | None = None  # the ensemble's spread ratio of this round
        p = self.method.surrogate_probability
        self.w = config.evaluation_probability if p is None else p
        if state.optimizer is None and state.optimizer_init is not None:  # resumed: rebuild from data
            state.optimizer = self.make_optimizer(state.optimizer_init)
            if state.optimizer_state is not None:
                state.optimizer.load_state_dict(state.optimizer_state)
            state.optimizer_state = None

    def make_optimizer(self, init: dict[str, Any]) -> Optimizer:
        """The optimizer from its constructor arguments as data (`LoopState.optimizer_init`)."""
        return self.optimizer_cls(
            DesignSpace.from_dict(init["space"]), population=init["population"], budget=init["budget"],
            seed=init["seed"], num_objectives=init["num_objectives"], initial_designs=init["initial_designs"],
            **init["options"],
        )

    # -- bookkeeping -----------------------------------------------------------------------
    @property
    def outer_count(self) -> int:
        return 1 if not (self.method.retrain or self.method.narrow) else self.config.outer_iterations

    @property
    def rounds_per_outer(self) -> int:
        if self.method.rounds_setting is not None:
            return int(getattr(self.config, self.method.rounds_setting))
        if self.outer_count == 1 and self.config.outer_iterations > 1:  # no-retrain: N*J in one swarm
            return self.config.outer_iterations * self.config.optimizer_iterations
        return self.config.optimizer_iterations

    def elapsed(self) -> float:
        return self.state.elapsed + time.perf_counter() - self.started

    def checkpoint(self) -> None:
        self.state.rng_state = self.rng.bit_generator.state
        self.state.elapsed = self.elapsed()
        self.started = time.perf_counter()
        save_state(self.run_dir, self.state)

    def emit(self, phase: str, **extra: Any) -> None:
        if self.progress is None:
            return
        s = self.state
        training = 1 if self.shared else 0  # a training step per outer iteration
        total = self.outer_count * (self.rounds_per_outer + training) + 1
        done = s.outer * (self.rounds_per_outer + training)
        if s.phase == "optimize":
            done += training + s.inner
        if s.phase in ("final", "done"):
            done = total - (1 if s.phase == "final" else 0)
        c = s.counters
        eta, elapsed = self.eta_seconds(), self.elapsed()
        # the share of the time, once the ETA is known; else the share of the steps
        fraction = elapsed / (elapsed + eta) if eta is not None and elapsed + eta > 0 else min(done / total, 1.0)
        self.progress({
            "phase": phase, "outer": s.outer, "outer_total": self.outer_count, "inner": s.inner,
            "inner_total": self.rounds_per_outer, "fraction": fraction,
            "best_cost": None if s.best_real is None else s.best_real[1],
            "best_any": None if s.best_any is None else s.best_any[1],
            "interactions": int(c["train_interactions"] + c["eval_interactions"] + c["final_interactions"]),
            "elapsed": elapsed, "eta": eta, **extra,
        })

    def eta_seconds(self) -> float | None:
        """Seconds left, from the wall clock this run has measured (the counters are part of
        the state, so this holds right after a resume): the training phases still to come at
        the measured seconds per training interaction; the rounds still to come at the
        measured seconds of a real round and of a surrogate round (each including the
        pseudo-critics' fits it triggered), a share 1 - w of them real (the share seen so far
        under the uncertainty policy); the final check at the measured rollout seconds per
        design, for its designs and one block. None until a training phase (when one is to
        come) and a real round have been timed. The video is not included."""
        s, c = self.state, self.config
        cnt = s.counters
        if s.phase == "done":
            return 0.0
        real_rounds, real_wall = cnt.get("real_rounds_timed", 0), cnt.get("real_round_wall", 0.0)
        if real_rounds <= 0:
            return None
        per_real = real_wall / real_rounds
        surrogate_rounds = cnt.get("surrogate_rounds_timed", 0)
        per_surrogate = cnt.get("surrogate_round_wall", 0.0) / surrogate_rounds if surrogate_rounds else 0.5 * per_real
        # training phases still to come (this outer iteration's if it has not trained yet)
        steps_left = 0
        if self.shared and not (self.pretrained and not self.method.retrain):
            first = s.outer if s.phase == "train" else s.outer + 1
            for outer in range(first, self.outer_count):
                if outer == 0 or self.method.retrain:
                    steps_left += c.train_steps if outer == 0 else c.retrain_steps
        train_wall, train_steps = cnt.get("train_wall", 0.0), cnt.get("train_steps_timed", 0)
        if steps_left and train_steps <= 0:
            return None
        seconds = steps_left * (train_wall / train_steps if train_steps else 0.0)
        if s.phase in ("train", "optimize"):
            rounds_left = self.rounds_per_outer * (self.outer_count - s.outer) - (s.inner if s.phase == "optimize" else 0)
            real_share = 1.0 - self.w
            if c.evaluation_policy == "uncertainty" and self.method.surrogate_probability is None:
                real_share = real_rounds / (real_rounds + surrogate_rounds)
            seconds += rounds_left * (real_share * per_real + (1 - real_share) * per_surrogate)
        real = [b for b in s.batches if b.get("kind") == "real"]
        per_design = sum(b["seconds"] for b in real) / max(sum(b["designs"] for b in real), 1)
        designs = (len(s.top_real) + 2) if len(self.objectives) == 1 else c.population + 1
        return float(seconds + per_design * designs)

    def seed_for(self, *parts: int) -> int:
        """A seed fixed by position in the run, so a resumed run draws what it would have."""
        return int(np.random.SeedSequence([self.config.seed, *parts]).generate_state(1)[0] % (2**31 - 1))

    def scenario_seed(self, block: int = 0) -> int:
        """The seed of the run's scenario set (common random numbers, docs/coadaptation.md):
        block 0 serves every real round, so all designs of a run are compared on the same
        scenarios; the final check adds blocks 1, 2, ... (fresh scenarios, same seed)."""
        return scenario_seed(self.config.seed, block)

    def get_backend(self) -> CoadaptationBackend:
        if self.backend is None:
            self.backend = self.backend_factory(self.seed_for(0))
            self._fitted_for = None
            if self.state.backend_checkpoint:
                self.backend.load(str(self.run_dir / self.state.backend_checkpoint))
        return self.backend

    def optimizer_options(self) -> dict[str, Any]:
        """The run's `optimizer_options`, as the optimizer plugin declared them (checked
        against its `option_specs` by the optimizer's constructor). An optimizer that keeps a
        study (it declares `study_name` / `storage`, as BO does) keeps it in the run's results
        store under `<run id>-outer<k>` unless told otherwise: optuna's tools and
        optuna-dashboard read it there, and no two runs of a grid share a name."""
        options = dict(self.config.optimizer_options)
        declared = {spec.name for spec in getattr(self.optimizer_cls, "option_specs", ())}
        if "study_name" in declared and not options.get("study_name"):
            options["study_name"] = f"{self.state.run_id}-outer{self.state.outer}"
        url = getattr(self.recorder, "url", None)
        if "storage" in declared and not options.get("storage") and isinstance(url, str) and "://" in url:
            options["storage"] = url
        return options

    # -- the phases ------------------------------------------------------------------------
    def run(self) -> dict[str, Any]:
        s = self.state
        while s.phase != "done":
            if s.phase == "train":
                self.train_phase()
            elif s.phase == "optimize":
                self.optimize_round()
            elif s.phase == "final":
                self.final_phase()
        assert s.summary is not None
        return s.summary

    def train_phase(self) -> None:
        """Algorithm 4 lines 10-11 and the set-up of this outer iteration's optimizer."""
        s, c = self.state, self.config
        space = DesignSpace.from_dict(s.space)
        s.spaces.append(space.to_dict())
        population = 1 if self.optimizer_cls.sequential else c.population
        s.train_designs, initial = None, None
        if self.shared:
            s.train_designs = space.sample(c.population, self.rng)  # [K, dim], line 10
            initial = s.train_designs[:population] if population == c.population else None
            self.train_shared_policy()
        s.optimizer_init = {
            "space": space.to_dict(), "population": population, "budget": self.rounds_per_outer,
            "seed": self.seed_for(2, s.outer), "num_objectives": len(self.objectives),
            "initial_designs": initial, "options": self.optimizer_options(),
        }
        s.optimizer = self.make_optimizer(s.optimizer_init)
        s.phase, s.inner = "optimize", 0
        self.checkpoint()

    def train_shared_policy(self) -> None:
        """Algorithm 4 line 11: (re)train the shared policy on this outer iteration's designs
        and checkpoint it."""
        s, c = self.state, self.config
        steps = c.train_steps if s.outer == 0 else c.retrain_steps
        if self.pretrained and not self.method.retrain:
            # no-retrain starting from a universal policy over the full range trains nothing,
            # as the paper's (0 training interactions in its Table 7)
            steps = 0
        if (s.outer == 0 or self.method.retrain) and steps > 0:
            s.labels = []  # a new policy: earlier real rounds no longer label it
            self._fitted_for = None
            self.emit("training")
            t0 = time.perf_counter()
            result = self.get_backend().train(s.train_designs, steps, seed=self.seed_for(1, s.outer))
            s.counters["train_wall"] = s.counters.get("train_wall", 0.0) + time.perf_counter() - t0
            s.counters["train_steps_timed"] = s.counters.get("train_steps_timed", 0) + int(steps)
            self.count_training([result])
            if self.method.buffer_from_training and getattr(result, "buffer", None) is not None:
                s.buffer, s.buffer_outer = result.buffer, s.outer
                s.buffer_serial += 1
        path = self.run_dir / "checkpoints" / f"backend-outer{s.outer}.pt"
        path.parent.mkdir(exist_ok=True)
        self.get_backend().save(str(path))
        s.backend_checkpoint = str(path.relative_to(self.run_dir))
        self.recorder.record_checkpoint(s.run_id, outer=s.outer, path=str(path))

    def count_training(self, results: Sequence[TrainingResult]) -> None:
        """Training phases into the counters and the recorder (the shared policy's, or the
        per-design policies a real evaluation trained first: `RealFitness.training`)."""
        s = self.state
        for result in results:
            s.counters["train_interactions"] += int(result.steps)
            s.counters["train_seconds"] += float(result.seconds)
            self.recorder.record_training(s.run_id, outer=s.outer, result=result)

    def choose_kind(self, designs: np.ndarray | None = None) -> str:
        """Hybrid evaluation (Algorithm 4 line 14): surrogate with probability w, else real.
        The draw is made every round so the random stream does not depend on the buffer; the
        surrogate needs an evaluation buffer from the current policy, so without one the
        round is real (the first of each outer iteration, unless training filled it).

        `evaluation_policy: uncertainty` (method ours only; beyond the paper): the fitted
        ensemble predicts the round's designs, and the round is a surrogate round when its
        members agree — their spread over the designs' spread (`spread_ratio`) at most
        `uncertainty_threshold` — else real. No fit (no real round of this policy yet, or a
        backend without an ensemble): real."""
        s, c = self.state, self.config
        draw = self.rng.random()
        self._last_uncertainty = None
        if s.buffer is None or s.buffer_outer != s.outer:
            return "real"
        if s.no_critic and not self.ensure_fitted():
            # an objective without a pseudo-critic in the starting policy: the fit to this
            # policy's real rounds stands in for it, or the round is real (setup.objectives_without_critic)
            return "real"
        if c.evaluation_policy == "uncertainty" and self.method.surrogate_probability is None and designs is not None:
            members_of = getattr(self.get_backend(), "surrogate_members", None)
            if members_of is None or not self.ensure_fitted():
                return "real"
            t0 = time.perf_counter()
            members = members_of(designs, self.objectives, s.buffer, samples=c.surrogate_samples,
                                 seed=self.seed_for(3, s.outer, s.inner))
            s.counters["surrogate_seconds"] += time.perf_counter() - t0
            if members is None:
                return "real"
            members = np.asarray(members, dtype=float).reshape(-1, len(designs), len(self.objectives))
            self._last_uncertainty = spread_ratio(members)
            if self._last_uncertainty <= c.uncertainty_threshold:
                self._pending = (s.inner, members.mean(axis=0))
                return "surrogate"
            return "real"
        return "surrogate" if draw < self.w else "real"

    def ensure_fitted(self) -> bool:
        """Fit the backend's pseudo-critics to this policy's real rounds (`LoopState.labels`)
        unless its fit already covers them (also after a resume: the fit is a function of the
        labels, the buffer and the seed). False when there is nothing to fit or no fit."""
        s, c = self.state, self.config
        backend = self.get_backend()
        fit = getattr(backend, "fit_surrogate", None)
        if not c.fit_surrogate or fit is None or not s.labels or s.buffer is None or s.buffer_outer != s.outer:
            return False
        key = (s.outer, len(s.labels), s.buffer_serial)
        if self._fitted_for != key:
            t0 = time.perf_counter()
            designs = np.concatenate([np.asarray(item["designs"], dtype=float) for item in s.labels])
            costs = np.concatenate([np.asarray(item["costs"], dtype=float) for item in s.labels])
            fit(designs, costs, self.objectives, s.buffer, seed=self.seed_for(6, s.outer, len(s.labels)))
            s.counters["surrogate_seconds"] += time.perf_counter() - t0
            self._fitted_for = key
        return True

    def reference_level(self, fit: RealFitness | None = None) -> np.ndarray | None:
        """The cost rule's reference level [M] for the current policy (`capped`: the nominal
        design's median scenario cost on the run's scenario set). The nominal design is
        evaluated once per policy (per outer iteration; once per run without a shared policy)
        and its interactions count as evaluation. None when the rule needs none or `fit` has
        no per-scenario costs (a backend without them reports its own costs)."""
        s, c = self.state, self.config
        if not self.cost_rule.needs_reference or (fit is not None and fit.per_scenario is None):
            return None
        key = s.outer if self.shared else 0
        if s.reference is not None and s.reference_outer == key:
            return np.asarray(s.reference, dtype=float)
        nominal = self.get_backend().real_fitness(self.nominal[None, :], self.objectives, agents=c.evaluation_agents,
                                                  steps=c.eval_steps, seed=self.scenario_seed())
        self.count_training(nominal.training)
        s.counters["eval_interactions"] += int(nominal.interactions)
        s.counters["eval_seconds"] += float(nominal.seconds)
        if nominal.per_scenario is None:
            return None
        falls = None if nominal.scenario_falls is None else np.asarray(nominal.scenario_falls)[0]
        ref = self.cost_rule.reference(np.asarray(nominal.per_scenario, dtype=float)[0], falls)
        s.reference, s.reference_outer = [float(x) for x in ref], key
        return ref

    def rule_costs(self, fit: RealFitness) -> np.ndarray:
        """[K, M] the costs of a real evaluation under the run's cost rule (`cost_rule`), from
        its per-scenario costs and falls; the backend's own costs when it gives none."""
        if fit.per_scenario is None:
            return np.asarray(fit.costs, dtype=float)
        return self.cost_rule.cost(fit.per_scenario, fit.scenario_falls, self.reference_level(fit))

    def optimize_round(self) -> None:
        """One optimizer ask/tell round (Algorithm 4 lines 13-20)."""
        s = self.state
        opt = s.optimizer
        assert opt is not None
        if opt.done:
            self.end_outer()
            return
        t0 = time.perf_counter()
        designs = opt.ask()  # [P, dim]
        initial = (s.optimizer_init or {}).get("initial_designs")
        if s.inner == 0 and initial is not None:  # the swarm starts from the training designs (line 10)
            self._check_first_round(np.asarray(initial, dtype=float), designs)
        kind = self.choose_kind(designs)
        self.emit(f"{kind} evaluation")
        costs, interactions, seconds, errors = self.evaluate(designs, kind)
        target = costs[:, 0] if len(self.objectives) == 1 else costs
        opt.tell(designs, target)
        self.record_batch(designs, costs, kind, interactions, seconds, errors)
        s.inner += 1
        # wall clock per kind of round, for the ETA (`eta_seconds`); saved with the state
        s.counters[f"{kind}_round_wall"] = s.counters.get(f"{kind}_round_wall", 0.0) + time.perf_counter() - t0
        s.counters[f"{kind}_rounds_timed"] = s.counters.get(f"{kind}_rounds_timed", 0) + 1
        self.checkpoint()
        self.emit("evaluated", kind=kind)

    def _check_first_round(self, initial: np.ndarray, designs: np.ndarray) -> None:
        """Say (once per run, stderr and the summary's notes) when the optimizer's first round
        is not the initial designs it was built with (`setup.initial_designs_note` probes for
        it before training where it can)."""
        from coadapt_core.coadapt.setup import first_round_note

        rows = 1 if self.optimizer_cls.sequential else len(initial)
        note = first_round_note(self.optimizer_cls.name, initial[:rows], designs)
        if note is not None and not any(n.startswith(f"warning: {note[:40]}") for n in self.state.notes):
            self.state.notes.append(f"warning: {note}")
            print(f"warning: {note}", file=sys.stderr)

    def evaluate(self, designs: np.ndarray, kind: str) -> tuple[np.ndarray, int, float, np.ndarray | None]:
        """costs [P, M], interactions, seconds, surrogate errors [P, M] (real rounds only)."""
        s, c = self.state, self.config
        backend = self.get_backend()
        seed = self.seed_for(3, s.outer, s.inner)
        if kind == "real":  # every real round on the run's one scenario set (paired designs)
            # a surrogate round would have been allowed here (a real round of this policy came
            # before): its prediction, made before this round's costs are known, is what the
            # quality figures judge (the first round of a policy: the paper's estimator on its
            # own buffer, marked not eligible)
            eligible = s.buffer is not None and s.buffer_outer == s.outer
            fitted = eligible and c.measure_surrogate_error and self.ensure_fitted()
            previous = s.buffer
            fit = backend.real_fitness(designs, self.objectives, agents=c.evaluation_agents, steps=c.eval_steps, seed=self.scenario_seed())
            self.count_training(fit.training)
            s.buffer, s.buffer_outer = fit.buffer, s.outer  # line 15: R_eval from this rollout
            s.buffer_serial += 1
            costs = self.rule_costs(fit).reshape(len(designs), -1)
            errors = None
            if c.measure_surrogate_error and self.shared:  # no shared policy, no surrogate
                t0 = time.perf_counter()
                states = previous if eligible else fit.buffer
                members_of = getattr(backend, "surrogate_members", None)
                members = None
                if fitted and members_of is not None:  # the members too: their spread ratio is recorded
                    members = members_of(designs, self.objectives, states, samples=c.surrogate_samples, seed=seed)
                if members is not None:
                    members = np.asarray(members, dtype=float).reshape(-1, *costs.shape)
                    predicted = members.mean(axis=0)
                else:
                    predicted = backend.surrogate_fitness(designs, self.objectives, states, samples=c.surrogate_samples, seed=seed)
                s.counters["surrogate_seconds"] += time.perf_counter() - t0
                predicted = np.asarray(predicted, dtype=float).reshape(costs.shape)
                errors = predicted - costs
                self.record_quality(predicted, costs, eligible=eligible, fitted=fitted,
                                    spread=None if members is None else spread_ratio(members))
            s.labels.append({"designs": designs.tolist(), "costs": costs.tolist()})
            s.counters["eval_interactions"] += int(fit.interactions)
            s.counters["eval_seconds"] += float(fit.seconds)
            s.counters["real_evaluations"] += 1
            if fit.survival is not None:
                self._last_survival = float(np.mean(fit.survival))
            self._last_tracking = walking(fit)["tracking_ratio"]
            self._last_errors = batch_errors(fit, self.cost_rule, self.reference_level(fit))
            return costs, int(fit.interactions), float(fit.seconds), errors
        t0 = time.perf_counter()
        # the round's seconds include a fit it needs: counted once (ensure_fitted counts it too)
        counted = s.counters["surrogate_seconds"]
        if self._pending is not None and self._pending[0] == s.inner:  # the ensemble's, just computed
            predicted = self._pending[1]
        else:
            self.ensure_fitted()
            predicted = backend.surrogate_fitness(designs, self.objectives, s.buffer, samples=c.surrogate_samples, seed=seed)
        self._pending = None
        seconds = time.perf_counter() - t0
        s.counters["surrogate_seconds"] = counted + seconds
        s.counters["eval_seconds"] += seconds
        s.counters["surrogate_evaluations"] += 1
        return np.asarray(predicted, dtype=float).reshape(len(designs), -1), 0, seconds, None

    def record_quality(self, predicted: np.ndarray, costs: np.ndarray, *, eligible: bool, fitted: bool,
                       spread: float | None = None) -> None:
        """One entry of `surrogate_quality.rounds`: the round's (surrogate, real) pairs per
        objective and their figures (coadapt_core/surrogate_quality.py), and the fitted
        ensemble's spread ratio on the round (what the uncertainty policy would have seen)."""
        s = self.state
        entry: dict[str, Any] = {"outer": s.outer, "inner": s.inner, "eligible": bool(eligible),
                                 "estimator": "fitted" if fitted else "paper", "spread_ratio": spread, "objectives": {}}
        for j, name in enumerate(self.names):
            pairs = {"surrogate": predicted[:, j].tolist(), "real": costs[:, j].tolist()}
            entry["objectives"][name] = {**quality_of(pairs["surrogate"], pairs["real"]), **pairs}
        s.quality_rounds.append(sq.clean(entry))
        from coadapt_core import tracking

        tracking.log_values("surrogate_quality", {
            f"{name}_{m}": q[m] for name, q in entry["objectives"].items() for m in sq.METRICS
            if isinstance(q.get(m), float) and np.isfinite(q[m])
        } | {"eligible": float(eligible)}, len(s.quality_rounds))

    def surrogate_quality(self) -> dict[str, Any]:
        """summary.json's `surrogate_quality`: pooled over the eligible rounds (those where a
        surrogate round was allowed: what the surrogate rounds of the run relied on), the
        first objective's figures in `pooled`, every objective's in `by_objective`."""
        rounds = self.state.quality_rounds
        used = [r for r in rounds if r["eligible"]]
        by_objective = {}
        for name in self.names:
            pairs = [{"surrogate": _floats(r["objectives"][name]["surrogate"]), "real": _floats(r["objectives"][name]["real"])}
                     for r in used if name in r["objectives"]]
            by_objective[name] = sq.clean(sq.pooled(pairs))
        brief = [{k: v for k, v in r.items() if k != "objectives"}
                 | {"objectives": {n: {m: q.get(m) for m in (*sq.METRICS, "n")} for n, q in r["objectives"].items()}}
                 for r in rounds]
        return {
            "pooled": by_objective[self.names[0]] if self.names else {},
            "by_objective": by_objective,
            "rounds": brief,
            "estimator": "fitted" if self.config.fit_surrogate else "paper",
            "definition": "over eligible real rounds (a real round of the same policy came before); relative error "
                          "(surrogate - real) / |real|; top_k_regret: (best real cost among the surrogate's "
                          f"{sq.TOP_K} cheapest - best real cost) / |best real cost|, mean over rounds",
        }

    def _keep_top(self, design: np.ndarray, cost: float) -> None:
        """The `final_candidates` lowest real costs over distinct designs (a noisy evaluation
        flatters the luckiest design; the final check re-evaluates several)."""
        top = self.state.top_real
        for i, (other, other_cost) in enumerate(top):
            if np.allclose(other, design):
                if cost < other_cost:
                    top[i] = (design.tolist(), cost)
                break
        else:
            top.append((design.tolist(), cost))
        top.sort(key=lambda item: item[1])
        del top[self.config.final_candidates:]

    def record_batch(self, designs, costs, kind, interactions, seconds, errors) -> None:
        s = self.state
        n = len(designs)
        s.counters["designs_evaluated"] += n
        for design, cost in zip(designs, costs[:, 0], strict=True):
            if not np.isfinite(cost):
                continue
            if s.best_any is None or cost < s.best_any[1]:
                s.best_any = (design.tolist(), float(cost), kind)
            if kind == "real" and (s.best_real is None or cost < s.best_real[1]):
                s.best_real = (design.tolist(), float(cost))
            if kind == "real":
                self._keep_top(design, float(cost))
        cost_dicts = [dict(zip(self.names, map(float, row), strict=True)) for row in costs]
        error_dicts = None if errors is None else [dict(zip(self.names, map(float, row), strict=True)) for row in errors]
        shares, secs = _split(int(interactions), n), _split(float(seconds), n)
        self.recorder.record_evaluations(s.run_id, outer=s.outer, inner=s.inner, designs=designs.tolist(), costs=cost_dicts,
                                         kind=kind, interactions=shares, seconds=secs, surrogate_errors=error_dicts)
        finite = np.isfinite(costs[:, 0])
        error_finite = None if errors is None else np.isfinite(errors[:, 0])
        s.batches.append({
            "outer": s.outer, "inner": s.inner, "kind": kind, "designs": n, "interactions": int(interactions),
            "seconds": float(seconds),
            "best_cost": float(costs[finite, 0].min()) if finite.any() else None,
            "mean_cost": float(costs[finite, 0].mean()) if finite.any() else None,
            # a diverged pseudo-critic gives NaN/inf: counted, and told to the optimizer as worst
            "nonfinite_costs": int((~finite).sum()),
            "surrogate_abs_error": float(np.abs(errors[error_finite, 0]).mean()) if errors is not None and error_finite.any() else None,
            "survival": self._last_survival,
            "tracking_ratio": self._last_tracking,
            **self._last_errors,  # real rounds: best design's cost SE, median relative SE, fall rate
            "uncertainty": self._last_uncertainty,
        })
        self._last_uncertainty = None
        self._last_survival = self._last_tracking = None
        self._last_errors = {}

    def end_outer(self) -> None:
        """Algorithm 4 line 22: the next range, around the final particles."""
        s, c = self.state, self.config
        space = DesignSpace.from_dict(s.space)
        if self.method.narrow:
            narrowed = space.narrow(
                s.optimizer.final_population(), margin=c.narrow_margin, min_width_fraction=c.narrow_min_width,
                reference=self.full_space,
            )
            s.space = narrowed.to_dict()
        s.outer += 1
        s.inner = 0
        s.phase = "train" if s.outer < self.outer_count else "final"
        self.checkpoint()

    def final_phase(self) -> None:
        """Re-evaluate for real the best designs (best real, best of any kind; the Pareto front
        for several objectives) and the nominal design, with the final policy."""
        s, c = self.state, self.config
        self.emit("final evaluation")
        if len(self.objectives) > 1:
            front, _ = s.optimizer.pareto_front()  # sorted by the first cost
            if len(front) > c.population:  # evenly along the front, both ends included
                front = front[np.unique(np.linspace(0, len(front) - 1, c.population).round().astype(int))]
            candidates = list(front)
        else:
            candidates = []
            for item in [*s.top_real, s.best_any]:
                if item is not None and not any(np.allclose(item[0], x) for x in candidates):
                    candidates.append(np.asarray(item[0]))
        designs = np.stack([*candidates, self.nominal])  # [C + 1, dim]
        uncertainty = no_uncertainty(self.names)
        final_walking: dict[str, dict[str, Any]] = {}
        if not self.shared:
            # every real cost came with the design's own policy: the best one stands, and the
            # nominal design is evaluated with a policy of its own
            best_design, best_cost = np.asarray(s.best_real[0]), s.best_real[1]
            fit = self.get_backend().real_fitness(
                self.nominal[None, :], self.objectives, agents=c.evaluation_agents, steps=c.eval_steps,
                seed=self.scenario_seed())
            self.count_training(fit.training)
            s.counters["final_interactions"] += int(fit.interactions)
            s.counters["final_seconds"] += float(fit.seconds)
            nominal_costs = self.rule_costs(fit).reshape(-1)
            front = None
            best_costs = np.array([best_cost])
        else:
            # paired blocks of fresh scenarios until the improvement is >= 4 standard errors
            check = final_check(
                lambda d, block: self.get_backend().real_fitness(
                    d, self.objectives, agents=c.evaluation_agents, steps=c.eval_steps, seed=self.scenario_seed(block)),
                designs, self.objectives, max_blocks=c.final_max_blocks, min_blocks=min(c.final_min_blocks, c.final_max_blocks),
                rule=self.cost_rule, fall_tolerance=c.fall_tolerance if len(self.objectives) == 1 else None,
                on_block=lambda b: self.emit(f"final check, scenario block {b}"),
            )
            fit = check.fit
            uncertainty = check.uncertainty(self.names)
            costs = np.asarray(fit.costs, dtype=float).reshape(len(designs), -1)
            s.counters["final_interactions"] += int(fit.interactions)
            s.counters["final_seconds"] += float(fit.seconds)
            nominal_costs = costs[-1]
            front = None
            if len(self.objectives) > 1:
                # the optimizer's front mixes surrogate and noisy real costs: the stored front
                # is the non-dominated subset of the final real re-evaluation
                front_designs, front_costs = pareto_front(designs[:-1], costs[:-1])
                front = {"designs": front_designs.tolist(),
                         "costs": [dict(zip(self.names, map(float, r), strict=True)) for r in front_costs]}
                best_design, best_costs = front_designs[0], front_costs[0]  # lowest first cost
                i = int(np.flatnonzero(np.all(np.isclose(designs[:-1], best_design), axis=1))[0])
            else:
                i = check.best  # the lowest cost among candidates that do not fall more (the nominal design if none)
                best_design, best_costs = designs[i], costs[i]
            best_cost = float(best_costs[0])
            final_walking = {"best": walking(fit, [i]), "nominal": walking(fit, [len(designs) - 1])}
        improvements = {
            o.name: float(o.improvement(float(best_costs[j]) if j < len(best_costs) else float("nan"), float(nominal_costs[j])))
            for j, o in enumerate(self.objectives) if j < len(best_costs)
        }
        cnt = s.counters
        interactions = int(cnt["train_interactions"] + cnt["eval_interactions"] + cnt["final_interactions"])
        summary = {
            "run_id": s.run_id,
            "method": c.method, "optimizer": self.optimizer_cls.name, "objective": c.objective, "terrain": c.terrain,
            "seed": c.seed, "preset": c.preset,
            "best_design": [float(x) for x in best_design],
            "best_cost": float(best_cost),
            "best_costs": dict(zip(self.names, map(float, best_costs), strict=False)),
            "nominal_design": self.nominal.tolist(),
            "nominal_cost": float(nominal_costs[0]),
            "nominal_costs": dict(zip(self.names, map(float, nominal_costs), strict=True)),
            "improvement": improvements[self.names[0]],
            "improvements": improvements,
            "interactions": interactions,
            "train_interactions": int(cnt["train_interactions"]),
            "eval_interactions": int(cnt["eval_interactions"]),
            "final_interactions": int(cnt["final_interactions"]),
            "seconds": self.elapsed(),
            "train_seconds": cnt["train_seconds"], "eval_seconds": cnt["eval_seconds"],
            "surrogate_seconds": cnt["surrogate_seconds"], "final_seconds": cnt["final_seconds"],
            "real_evaluations": int(cnt["real_evaluations"]), "surrogate_evaluations": int(cnt["surrogate_evaluations"]),
            "designs_evaluated": int(cnt["designs_evaluated"]),
            "spaces": s.spaces,
            "final_space": s.space,
            "batches": s.batches,
            "pareto_front": front,
            "evaluation_policy": c.evaluation_policy,
            "cost_rule": c.cost_rule, "cost_cap": c.cost_cap, "cost_reference": s.reference,
            "surrogate_quality": self.surrogate_quality(),
            # what a printed cost is: per-step mean of the final check's paired scenarios of
            # eval_steps steps each (costs of other commands or sizes are not comparable)
            "cost_units": {o.name: getattr(o, "unit", "") for o in self.objectives},
            "eval_steps": int(c.eval_steps),
        }
        summary["policy"] = s.policy
        summary["notes"] = list(s.notes)
        # a policy trained from scratch in this run (no starting policy, or the BO baseline's
        # per-design policies from scratch) is vouched for by nothing but this gate
        scratch = (str(c.checkpoint).strip().lower() == "none" if self.shared
                   else getattr(c, "specialized_init", "scratch") != "universal")
        summary["reliable"], summary["reliability"] = judge_short(s.batches, final_walking, c.eval_steps,
                                                                  from_scratch=scratch)
        summary["starting_policy"] = None if str(c.checkpoint).strip().lower() == "none" else _starting_policy(c)
        summary["final_walking"] = final_walking
        summary.update(uncertainty)
        summary.update(fall_verdict(summary))
        s.summary = summary
        s.phase = "done"
        self.checkpoint()
        # the store says "finished" once the caller's last step (`run_coadaptation(finishing=)`,
        # e.g. the CLI's video) is done too: an interrupt there leaves the run resumable
        self.emit("done")


def _check_same_policy(state: LoopState, policy: dict[str, Any] | None) -> None:
    """A resumed run starts from the policy file it started from: a file whose SHA-256
    changed since (a reinstalled plugin shipping a retrained policy, an overwritten path) is
    refused in one line. A run recorded before provenance existed takes today's."""
    recorded = (state.policy or {}).get("sha256")
    if policy is None or not recorded or state.phase == "done":
        state.policy = state.policy or policy
        return
    if policy.get("sha256") != recorded:
        now = policy.get("sha256")
        raise UserError(
            f"cannot resume run {state.run_id}: its starting policy {state.policy.get('path')} changed since the run "
            f"started (SHA-256 {recorded[:12]}... then, {now[:12] + '...' if now else 'no file'} now); restore that "
            "file, or start a new run", field="resume")


# ------------------------------------------------------------------------------------------
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
    (mixed for `mixed` or an optimizer that implies it) narrowed to `design_ranges`, its nominal design, the
    objectives, the optimizer class and the universal-policy backend. With `resume` (a run
    folder) the recorded config and state are used and `config` is ignored.

    `on_start(run_id, run_dir)` is called as soon as the run folder holds a state to resume
    from; `finishing(result)` after the final check and before the store says "finished"
    (the CLI renders its video there). An interrupt anywhere (Ctrl-C included) marks the run
    "interrupted" and propagates; `resume=run_dir` continues from the last state written.
    """
    if resume is not None:
        run_path = Path(resume).absolute()
        state = load_state(run_path)
        config = config_from_dict(state.config)
        _check_writable(run_path, state)
    else:
        if config is None:
            raise UserError("run_coadaptation needs a config or a run folder to resume", field="config")
        config.validate()
        state = None
        run_path = None
    parts = build_parts(config, design_space=design_space, nominal_design=nominal_design, objectives=objectives,
                        optimizer_cls=optimizer_cls, backend_factory=backend_factory)
    if state is None:
        run_id = (new_run_id(config.method, config.objective.split(","), config.seed, config.optimizer)
                  if run_dir is None else Path(run_dir).name)
        run_path = (Path(run_dir) if run_dir is not None else Path(config.out) / run_id).absolute()
        if (run_path / STATE_FILE).exists():
            raise UserError(f"run folder '{run_path}' already holds a run; resume it or pick another", field="out")
        run_path.mkdir(parents=True, exist_ok=True)
        recorder = recorder or make_recorder(run_path, config.store or None)  # a bad store: one line, nothing written
        state = LoopState(run_id=run_id, config=config.to_dict(), space=parts.space.to_dict(), policy=parts.policy,
                          notes=list(parts.notes), no_critic=list(parts.no_critic))
        for note in parts.notes:
            print(note, file=sys.stderr)
        # the state first, then the store's row: a run the store knows can always be resumed
        # (a grid killed in between used to leave a row "running" over a folder without one)
        save_state(run_path, state)
    else:
        _check_same_policy(state, parts.policy)
    assert run_path is not None
    recorder = recorder or make_recorder(run_path, config.store or None)
    if on_start is not None:
        on_start(state.run_id, run_path)
    recorder.start_run({**config.to_dict(), "run_id": state.run_id, "run_dir": str(run_path),
                        "design_space": parts.full_space.to_dict(), "policy": state.policy})
    try:
        if resume is not None:
            # a store that lost this run's rows (emptied, replaced, an old copy) gets them back
            # from the run folder's JSON lines before anything new is recorded
            refill = getattr(recorder, "refill_from_run_folder", None)
            if refill is not None:
                refill(state.run_id, run_path)
        if state.phase == "done":  # resuming a finished run (or one stopped in `finishing`)
            assert state.summary is not None
            summary = state.summary
        else:
            summary = _continue(config, state, parts, run_path, recorder, progress)
        result = CoadaptResult(state.run_id, run_path, summary)
        if finishing is not None:
            finishing(result)
    except BaseException as exc:
        # the last state stays in the run folder; `resume=run_dir` continues from it. A failure
        # to record that (a folder gone read-only) must not hide what stopped the run.
        with contextlib.suppress(Exception):
            recorder.finish(state.run_id, {"run_id": state.run_id, "error": f"{type(exc).__name__}: {exc}",
                                           "outer": state.outer, "inner": state.inner, "phase": state.phase},
                            "interrupted")
        raise
    recorder.finish(state.run_id, summary, "finished")
    return result


def _starting_policy(config: CoadaptConfig) -> str | None:
    """The policy the run started from, as a path (the robot's shipped one when not given)."""
    if config.checkpoint.strip():
        return config.checkpoint.strip()
    try:
        from coadapt_core.coadapt.setup import resolve_checkpoint

        found = resolve_checkpoint(config)
    except Exception:  # a fake or third-party robot without one
        return None
    return None if found is None else str(found)


def _check_writable(run_path: Path, state: LoopState) -> None:
    """A resumed run writes its folder: one that cannot be written is one line here, before
    the store or a logger thread (TensorBoard's) touches it."""
    probe = run_path / f".{state.run_id}.write-check"
    try:
        with open(probe, "wb"):
            pass
        probe.unlink()
    except OSError as exc:
        raise UserError(f"cannot resume: run folder '{run_path}' cannot be written ({exc.strerror or type(exc).__name__}); "
                        "make it writable, or copy it to a folder you can write and resume the copy",
                        field="resume") from None


def _continue(config: CoadaptConfig, state: LoopState, parts: Any, run_path: Path, recorder: RunRecorder,
              progress: ProgressFn | None) -> dict[str, Any]:
    """Run the loop from `state` to its summary, with the run's TensorBoard/wandb logger."""
    from coadapt_core import tracking

    # TensorBoard (default) / wandb: training curves, best cost per round, surrogate error
    logger = tracking.make_logger(getattr(config, "logger", "tensorboard"), run_path / "tb", name=state.run_id,
                                  config=config.to_dict())
    recorder = tracking.TrackingRecorder(recorder, logger)
    loop = CoadaptationLoop(
        config, backend_factory=parts.backend_factory, design_space=parts.full_space, nominal_design=parts.nominal,
        objectives=parts.objectives, optimizer_cls=parts.optimizer_cls, run_dir=run_path, recorder=recorder,
        state=state, progress=progress, pretrained=parts.pretrained,
    )
    try:
        with tracking.active(logger):
            summary = loop.run()
            recorder.log_final(summary)
            return summary
    finally:
        logger.close()
