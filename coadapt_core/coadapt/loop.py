"""Algorithm 4, design co-adaptation, as a small state machine over `LoopState`: sample
designs from the current range, (re)train the universal policy and pseudo-critics on them,
run the optimizer with hybrid real/surrogate fitness, narrow the range around the final
particles; finally re-evaluate the best design and the nominal one for real.

One code path serves every method of the paper's comparison, each a row of the method
registry (`coadapt_core.methods`): its switches, and the kind of backend its designs
are evaluated with (the universal policy, or a policy per design for the BO baseline). The
rooms around it: the state and its persistence (`state.py`: written after every training
phase and every evaluation batch, so a run continues where it stopped), the run's plan and
ETA (`schedule.py`), a training phase in chunks (`phase.py`), each outer iteration's
optimizer (`outer_optimizer.py`), the hybrid evaluation policy and the surrogate's records
(`hybrid.py`), the final phase (`final_phase.py` over `final_check.py`) and the summary
(`summary.py`); `run.py` starts or resumes a run (`run_coadaptation`) and drives this loop.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core import phase_progress
from coadapt_core.coadapt.config import CoadaptConfig
from coadapt_core.coadapt.final_check import batch_errors
from coadapt_core.coadapt.final_phase import check_final_designs, save_own_policies
from coadapt_core.coadapt.first_round import note_first_round
from coadapt_core.coadapt.hybrid import HybridPolicy
from coadapt_core.coadapt.outer_optimizer import make_optimizer, optimizer_init, optimizer_options
from coadapt_core.coadapt.phase import train_in_chunks
from coadapt_core.coadapt.refine import REFINE, refine_round, refinement_due
from coadapt_core.coadapt.reliability import walking
from coadapt_core.coadapt.schedule import Schedule
from coadapt_core.coadapt.state import LoopState, RoundRecord, save_state
from coadapt_core.coadapt.summary import final_candidates, run_summary
from coadapt_core.costs import CostRule
from coadapt_core.design_space import DesignSpace
from coadapt_core.fitness import CoadaptationBackend, RealFitness, RunRecorder, TrainingResult
from coadapt_core.methods import Method
from coadapt_core.objective import Objective
from coadapt_core.optimizer import Optimizer, follows_surrogate_slope
from coadapt_core.scenarios.seeds import scenario_seed

ProgressFn = Callable[[dict[str, Any]], None]


def seed_at(seed: int, *parts: int) -> int:
    """The seed at position `parts` of a run with seed `seed` (`CoadaptationLoop.seed_for`)."""
    return int(np.random.SeedSequence([seed, *parts]).generate_state(1)[0] % (2**31 - 1))


class CoadaptationLoop:
    """Runs Algorithm 4 as a small state machine over `LoopState` (see module docstring)."""

    def __init__(
        self,
        config: CoadaptConfig,
        *,
        method: Method,
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
        self.method = method
        # the method's backend shares one policy between designs (universal) or not (a
        # policy per design: nothing to train up front, no surrogate, real costs are final)
        self.shared = self.method.backend_kind.shared_policy
        self.schedule = Schedule.of(config, self.method, pretrained=pretrained)
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
        # which kind each round is, and the surrogate's side of it (hybrid.py)
        self.hybrid = HybridPolicy(
            config, self.method, self.objectives, state, self.rng, self.get_backend, self.seed_for
        )
        if state.optimizer is None and state.optimizer_init is not None:  # resumed: from data
            state.optimizer = make_optimizer(optimizer_cls, state.optimizer_init)
            if state.optimizer_state is not None:
                state.optimizer.load_state_dict(state.optimizer_state)
            state.optimizer_state = None

    # -- bookkeeping -----------------------------------------------------------------------
    def elapsed(self) -> float:
        return self.state.elapsed + time.perf_counter() - self.started

    def checkpoint(self) -> None:
        self.state.rng_state = self.rng.bit_generator.state
        self.state.elapsed = self.elapsed()
        self.started = time.perf_counter()
        save_state(self.run_dir, self.state)

    def emit(self, phase: str, **extra: Any) -> None:
        if self.progress is not None:
            eta, elapsed = self.eta_seconds(), self.elapsed()
            self.progress(self.schedule.progress_event(self.state, phase, elapsed, eta, **extra))

    def eta_seconds(self) -> float | None:
        """Seconds left (`Schedule.eta_seconds`), the hybrid policy's share of the rounds
        still to come real."""
        return self.schedule.eta_seconds(
            self.state, self.config.population, len(self.objectives), self.hybrid.real_share
        )

    def seed_for(self, *parts: int) -> int:
        """A seed fixed by position in the run, so a resumed run draws what it would have."""
        return seed_at(self.config.seed, *parts)

    def scenario_seed(self, block: int = 0) -> int:
        """The seed of the run's scenario set (common random numbers, docs/coadaptation.md):
        block 0 serves every real round, so all designs of a run are compared on the same
        scenarios; the final check adds blocks 1, 2, ... (fresh scenarios, same seed)."""
        return scenario_seed(self.config.seed, block)

    def get_backend(self) -> CoadaptationBackend:
        if self.backend is None:
            self.backend = self.backend_factory(self.seed_for(0))
            self.hybrid.forget_fit()
            if self.state.backend_checkpoint:
                self.backend.load(str(self.run_dir / self.state.backend_checkpoint))
        return self.backend

    # -- the phases ------------------------------------------------------------------------
    def run(self) -> dict[str, Any]:
        s = self.state
        while s.phase != "done":
            if s.phase == "train":
                self.train_phase()
            elif s.phase == "optimize":
                self.optimize_round()
            elif s.phase == REFINE:  # after the last outer iteration's optimizer (refine.py)
                refine_round(self)
            elif s.phase == "final":
                self.final_phase()
        assert s.summary is not None
        return s.summary

    def train_phase(self) -> None:
        """Algorithm 4 lines 10-11 and the set-up of this outer iteration's optimizer."""
        s, c = self.state, self.config
        space = DesignSpace.from_dict(s.space)
        if s.train_progress is None:  # else resumed inside the phase: its designs are drawn
            s.spaces.append(space.to_dict())
            # [K, dim], line 10
            s.train_designs = space.sample(c.population, self.rng) if self.shared else None
        population = 1 if self.optimizer_cls.sequential else c.population
        initial = None
        if self.shared:
            initial = s.train_designs[:population] if population == c.population else None
            self.train_shared_policy()
        options = optimizer_options(
            self.optimizer_cls,
            c.optimizer_options,
            run_name=f"{s.run_id}-outer{s.outer}",
            recorder=self.recorder,
            start=np.asarray(s.best_real[0]) if s.outer and s.best_real else self.nominal,
        )
        s.optimizer_init = optimizer_init(
            space,
            population=population,
            budget=self.schedule.rounds_per_outer,
            seed=self.seed_for(2, s.outer),
            num_objectives=len(self.objectives),
            initial_designs=initial,
            options=options,
        )
        s.optimizer = make_optimizer(self.optimizer_cls, s.optimizer_init)
        s.phase, s.inner = "optimize", 0
        self.checkpoint()

    def train_shared_policy(self) -> None:
        """Algorithm 4 line 11: (re)train the shared policy on this outer iteration's designs
        and checkpoint it."""
        s = self.state
        steps = self.schedule.training_steps(s.outer)
        if steps > 0:
            s.labels = []  # a new policy: earlier real rounds no longer label it
            self.hybrid.forget_fit()
            self.emit("training")
            t0 = time.perf_counter()
            # the phase's own count and ETA, from its measured rate
            rate = phase_progress.PhaseRate()

            def heard(done: int, total: int) -> None:
                self.emit(
                    "training", phase_done=done, phase_total=total, phase_eta=rate.eta(done, total)
                )

            # a checkpoint every checkpoint_interactions
            result = train_in_chunks(self, steps, heard)
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
        nominal = self.get_backend().real_fitness(
            self.nominal[None, :],
            self.objectives,
            agents=c.evaluation_agents,
            steps=c.eval_steps,
            seed=self.scenario_seed(),
        )
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
        follows = follows_surrogate_slope(opt)
        if follows:  # it steps along the surrogate; its every step is confirmed real
            opt.set_slope(self.hybrid.slope_oracle())
        designs = opt.ask()  # [P, dim]
        initial = (s.optimizer_init or {}).get("initial_designs")
        if s.inner == 0 and initial is not None:
            # the swarm starts from the training designs (line 10): say when it does not
            initial = np.asarray(initial, dtype=float)
            note_first_round(s.notes, self.optimizer_cls, initial, designs)
        kind, uncertainty = self.hybrid.choose_kind(designs)
        kind = "real" if follows else kind
        self.emit(f"{kind} evaluation")
        record = self.evaluate(designs, kind, uncertainty=uncertainty)
        opt.tell(designs, record.costs[:, 0] if len(self.objectives) == 1 else record.costs)
        self.record_batch(designs, record)
        if follows:  # the step, beside the round's real cost and its SE
            s.batches[-1]["descent_step"] = getattr(opt, "last_step", None)
        s.inner += 1
        # wall clock per kind of round, for the ETA (`eta_seconds`); saved with the state
        s.counters[f"{kind}_round_wall"] = (
            s.counters.get(f"{kind}_round_wall", 0.0) + time.perf_counter() - t0
        )
        s.counters[f"{kind}_rounds_timed"] = s.counters.get(f"{kind}_rounds_timed", 0) + 1
        self.checkpoint()
        self.emit("evaluated", kind=kind)

    def evaluate(
        self, designs: np.ndarray, kind: str, *, uncertainty: float | None = None
    ) -> RoundRecord:
        """The round's record: costs [P, M], what it spent, surrogate errors [P, M] and, for a
        real round, survival, tracking and error bars; `uncertainty` as the hybrid policy
        judged it."""
        s, c = self.state, self.config
        seed = self.seed_for(3, s.outer, s.inner)
        if kind != "real":
            costs, seconds = self.hybrid.surrogate_round(designs, seed)
            return RoundRecord(kind, costs, 0, seconds, uncertainty=uncertainty)
        # every real round on the run's one scenario set (paired designs); a surrogate round
        # would have been allowed here (a real round of this policy came before): its
        # prediction, made before this round's costs are known, is what the quality figures judge
        eligible, fitted, previous = self.hybrid.before_real_round()
        fit = self.get_backend().real_fitness(
            designs,
            self.objectives,
            agents=c.evaluation_agents,
            steps=c.eval_steps,
            seed=self.scenario_seed(),
        )
        self.count_training(fit.training)
        s.buffer, s.buffer_outer = fit.buffer, s.outer  # line 15: R_eval from this rollout
        s.buffer_serial += 1
        costs = self.rule_costs(fit).reshape(len(designs), -1)
        errors = None
        if c.measure_surrogate_error and self.shared:  # no shared policy, no surrogate
            errors = self.hybrid.judge_real_round(
                designs,
                costs,
                previous if eligible else fit.buffer,
                eligible=eligible,
                fitted=fitted,
                seed=seed,
            )
        s.labels.append({"designs": designs.tolist(), "costs": costs.tolist()})
        s.counters["eval_interactions"] += int(fit.interactions)
        s.counters["eval_seconds"] += float(fit.seconds)
        s.counters["real_evaluations"] += 1
        return RoundRecord(
            kind,
            costs,
            int(fit.interactions),
            float(fit.seconds),
            errors,
            survival=None if fit.survival is None else float(np.mean(fit.survival)),
            tracking_ratio=walking(fit)["tracking_ratio"],
            error_bars=batch_errors(fit, self.cost_rule, self.reference_level(fit)),
            uncertainty=uncertainty,
        )

    def record_batch(self, designs: np.ndarray, record: RoundRecord) -> None:
        """The round into the state (best costs, candidates, `batches`) and the recorder."""
        s = self.state
        s.counters["designs_evaluated"] += len(designs)
        s.note_costs(designs, record.costs[:, 0], record.kind, self.config.final_candidates)
        self.recorder.record_evaluations(
            s.run_id,
            outer=s.outer,
            inner=s.inner,
            designs=designs.tolist(),
            kind=record.kind,
            **record.per_design(self.names),
        )
        s.add_batch(record)

    def end_outer(self) -> None:
        """Algorithm 4 line 22: the next range, around the final particles."""
        if refinement_due(self):  # the last one's optimizer done: its best is refined first
            return
        s, c = self.state, self.config
        space = DesignSpace.from_dict(s.space)
        if self.method.narrow:
            narrowed = space.narrow(
                s.optimizer.final_population(),
                margin=c.narrow_margin,
                min_width_fraction=c.narrow_min_width,
                reference=self.full_space,
            )
            s.space = narrowed.to_dict()
        s.outer += 1
        s.inner = 0
        s.phase = "train" if s.outer < self.schedule.outer_count else "final"
        self.checkpoint()

    def final_phase(self) -> None:
        """Re-evaluate for real the best designs (best real, best of any kind; the Pareto front
        for several objectives) and the nominal design, with the final policy (or each its
        own), and write the run's summary."""
        s, c = self.state, self.config
        self.emit("final evaluation")
        candidates = final_candidates(s, s.optimizer, len(self.objectives), c.population)
        designs = np.stack([*candidates, self.nominal])  # [C + 1, dim]
        # with a policy per design: each candidate's own
        outcome, fit = check_final_designs(
            self._final_fitness,
            designs,
            self.objectives,
            c,
            self.cost_rule,
            on_block=lambda b: self.emit(f"final check, scenario block {b}"),
        )
        s.counters["final_interactions"] += int(fit.interactions)
        s.counters["final_seconds"] += float(fit.seconds)
        if not self.shared:
            outcome.uncertainty["own_policies"] = save_own_policies(
                self.get_backend(),
                self.run_dir,
                {"best": outcome.best_design, "nominal": self.nominal},
                self.count_training,
            )
        s.summary = run_summary(
            s,
            c,
            self.objectives,
            outcome,
            optimizer=self.optimizer_cls.name,
            nominal=self.nominal,
            seconds=self.elapsed(),
            surrogate_quality=self.hybrid.quality_summary(),
            shared=self.shared,
            backend=self.get_backend(),
        )
        s.phase = "done"
        self.checkpoint()
        # the store says "finished" once the caller's last step (`run_coadaptation(finishing=)`,
        # e.g. the CLI's video) is done too: an interrupt there leaves the run resumable
        self.emit("done")

    def _final_fitness(self, designs: np.ndarray, block: int) -> RealFitness:
        """One scenario block of the final check; policies a backend trains first count as
        training."""
        c = self.config
        fit = self.get_backend().real_fitness(
            designs,
            self.objectives,
            agents=c.evaluation_agents,
            steps=c.eval_steps,
            seed=self.scenario_seed(block),
        )
        self.count_training(fit.training)
        return fit
