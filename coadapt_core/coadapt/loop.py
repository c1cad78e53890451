"""Algorithm 4, design co-adaptation, as a small state machine over `LoopState`: sample
designs from the current range, (re)train the universal policy and pseudo-critics on them,
run the optimizer with hybrid real/surrogate fitness, narrow the range around the final
particles; finally re-evaluate the best design and the nominal one for real.

One code path serves every method of the paper's comparison, each a row of the method
registry (`coadapt_core.methods`): its switches, and the kind of backend its designs
are evaluated with (the universal policy, or a policy per design for the BO baseline). The
rooms around it: the state and its persistence (`state.py`: written after every training
phase and every evaluation batch, so a run continues where it stopped), the hybrid
evaluation policy and the surrogate's records (`hybrid.py`), the final check
(`final_check.py`) and the summary (`summary.py`); `run.py` starts or resumes a run
(`run_coadaptation`) and drives this loop.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from coadapt_core import phase_progress
from coadapt_core.coadapt.config import CoadaptConfig
from coadapt_core.coadapt.final_check import batch_errors, final_check
from coadapt_core.coadapt.hybrid import HybridPolicy
from coadapt_core.coadapt.phase import train_in_chunks
from coadapt_core.coadapt.reliability import walking
from coadapt_core.coadapt.setup import note_first_round
from coadapt_core.coadapt.specialized import OWN_POLICY_FILES, OwnPolicies
from coadapt_core.coadapt.state import LoopState, RoundRecord, save_state
from coadapt_core.coadapt.summary import (
    FinalOutcome,
    final_candidates,
    run_summary,
)
from coadapt_core.costs import CostRule
from coadapt_core.design_space import DesignSpace
from coadapt_core.fitness import CoadaptationBackend, RealFitness, RunRecorder, TrainingResult
from coadapt_core.methods import get_method
from coadapt_core.objective import Objective
from coadapt_core.optimizer import Optimizer
from coadapt_core.options import fill_from_run
from coadapt_core.pareto import front_rows
from coadapt_core.scenarios.seeds import scenario_seed

ProgressFn = Callable[[dict[str, Any]], None]


def _split(total: float, n: int) -> list[float]:
    """Share a batch's cost among its n designs (integers stay integers and sum exactly)."""
    if isinstance(total, int):
        base, rest = divmod(total, n)
        return [base + (1 if i < rest else 0) for i in range(n)]
    return [total / n] * n


def seed_at(seed: int, *parts: int) -> int:
    """The seed at position `parts` of a run with seed `seed` (`CoadaptationLoop.seed_for`)."""
    return int(np.random.SeedSequence([seed, *parts]).generate_state(1)[0] % (2**31 - 1))


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
        # which kind each round is, and the surrogate's side of it (hybrid.py)
        self.hybrid = HybridPolicy(
            config, self.method, self.objectives, state, self.rng, self.get_backend, self.seed_for
        )
        if (
            state.optimizer is None and state.optimizer_init is not None
        ):  # resumed: rebuild from data
            state.optimizer = self.make_optimizer(state.optimizer_init)
            if state.optimizer_state is not None:
                state.optimizer.load_state_dict(state.optimizer_state)
            state.optimizer_state = None

    def make_optimizer(self, init: dict[str, Any]) -> Optimizer:
        """The optimizer from its constructor arguments as data (`LoopState.optimizer_init`)."""
        return self.optimizer_cls(
            DesignSpace.from_dict(init["space"]),
            population=init["population"],
            budget=init["budget"],
            seed=init["seed"],
            num_objectives=init["num_objectives"],
            initial_designs=init["initial_designs"],
            **init["options"],
        )

    # -- bookkeeping -----------------------------------------------------------------------
    @property
    def outer_count(self) -> int:
        return (
            1 if not (self.method.retrain or self.method.narrow) else self.config.outer_iterations
        )

    @property
    def rounds_per_outer(self) -> int:
        if self.method.rounds_setting is not None:
            return int(getattr(self.config, self.method.rounds_setting))
        if (
            self.outer_count == 1 and self.config.outer_iterations > 1
        ):  # no-retrain: N*J in one swarm
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
        fraction = (
            elapsed / (elapsed + eta)
            if eta is not None and elapsed + eta > 0
            else min(done / total, 1.0)
        )
        self.progress(
            {
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
        )

    def eta_seconds(self) -> float | None:
        """Seconds left, from the wall clock this run has measured (the counters are part of
        the state, so this holds right after a resume): the training phases still to come at
        the measured seconds per training interaction; the rounds still to come at the
        measured seconds of a real round and of a surrogate round (each including the
        pseudo-critics' fits it triggered), the hybrid policy's share of them real
        (`HybridPolicy.real_share`); the final check at the measured rollout seconds per
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
        per_surrogate = (
            cnt.get("surrogate_round_wall", 0.0) / surrogate_rounds
            if surrogate_rounds
            else 0.5 * per_real
        )
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
            rounds_left = self.rounds_per_outer * (self.outer_count - s.outer) - (
                s.inner if s.phase == "optimize" else 0
            )
            real_share = self.hybrid.real_share(real_rounds, surrogate_rounds)
            seconds += rounds_left * (real_share * per_real + (1 - real_share) * per_surrogate)
        real = [b for b in s.batches if b.get("kind") == "real"]
        per_design = sum(b["seconds"] for b in real) / max(sum(b["designs"] for b in real), 1)
        designs = (len(s.top_real) + 2) if len(self.objectives) == 1 else c.population + 1
        return float(seconds + per_design * designs)

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

    def optimizer_options(self) -> dict[str, Any]:
        """The run's `optimizer_options`, as the optimizer plugin declared them (checked
        against its `option_specs` by the optimizer's constructor), with the options it
        declares `from_run` filled where the run leaves them unset (`coadapt_core.options`):
        a study kept under `<run id>-outer<k>` in the run's results store, where a study
        browser reads it and no two runs of a grid share a name."""
        url = getattr(self.recorder, "url", None)
        facts = {
            "run_name": f"{self.state.run_id}-outer{self.state.outer}",
            "store_url": url if isinstance(url, str) and "://" in url else None,
        }
        return fill_from_run(
            getattr(self.optimizer_cls, "option_specs", ()), self.config.optimizer_options, facts
        )

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
        if (
            s.train_progress is None
        ):  # else resumed inside the phase: its designs are drawn (phase.py)
            s.spaces.append(space.to_dict())
            s.train_designs = (
                space.sample(c.population, self.rng) if self.shared else None
            )  # [K, dim], line 10
        population = 1 if self.optimizer_cls.sequential else c.population
        initial = None
        if self.shared:
            initial = s.train_designs[:population] if population == c.population else None
            self.train_shared_policy()
        s.optimizer_init = {
            "space": space.to_dict(),
            "population": population,
            "budget": self.rounds_per_outer,
            "seed": self.seed_for(2, s.outer),
            "num_objectives": len(self.objectives),
            "initial_designs": initial,
            "options": self.optimizer_options(),
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
            self.hybrid.forget_fit()
            self.emit("training")
            t0 = time.perf_counter()
            rate = (
                phase_progress.PhaseRate()
            )  # the phase's own count and ETA, from its measured rate

            def heard(done: int, total: int) -> None:
                self.emit(
                    "training", phase_done=done, phase_total=total, phase_eta=rate.eta(done, total)
                )

            result = train_in_chunks(
                self, steps, heard
            )  # a checkpoint every checkpoint_interactions
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
        designs = opt.ask()  # [P, dim]
        initial = (s.optimizer_init or {}).get("initial_designs")
        if (
            s.inner == 0 and initial is not None
        ):  # the swarm starts from the training designs (line 10)
            note_first_round(
                self.state.notes, self.optimizer_cls, np.asarray(initial, dtype=float), designs
            )
        kind, uncertainty = self.hybrid.choose_kind(designs)
        self.emit(f"{kind} evaluation")
        record = self.evaluate(designs, kind, uncertainty=uncertainty)
        opt.tell(designs, record.costs[:, 0] if len(self.objectives) == 1 else record.costs)
        self.record_batch(designs, record)
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
        real round, survival, tracking and error bars; `uncertainty` as the hybrid policy judged it."""
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
        s = self.state
        n = len(designs)
        kind, costs, errors = record.kind, record.costs, record.surrogate_errors
        interactions, seconds = record.interactions, record.seconds
        s.counters["designs_evaluated"] += n
        s.note_costs(designs, costs[:, 0], kind, self.config.final_candidates)
        cost_dicts = [dict(zip(self.names, map(float, row), strict=True)) for row in costs]
        error_dicts = (
            None
            if errors is None
            else [dict(zip(self.names, map(float, row), strict=True)) for row in errors]
        )
        shares, secs = _split(int(interactions), n), _split(float(seconds), n)
        self.recorder.record_evaluations(
            s.run_id,
            outer=s.outer,
            inner=s.inner,
            designs=designs.tolist(),
            costs=cost_dicts,
            kind=kind,
            interactions=shares,
            seconds=secs,
            surrogate_errors=error_dicts,
        )
        s.add_batch(record)

    def end_outer(self) -> None:
        """Algorithm 4 line 22: the next range, around the final particles."""
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
        s.phase = "train" if s.outer < self.outer_count else "final"
        self.checkpoint()

    def final_phase(self) -> None:
        """Re-evaluate for real the best designs (best real, best of any kind; the Pareto front
        for several objectives) and the nominal design, with the final policy (or each its own)."""
        s, c = self.state, self.config
        self.emit("final evaluation")
        candidates = final_candidates(s, s.optimizer, len(self.objectives), c.population)
        designs = np.stack([*candidates, self.nominal])  # [C + 1, dim]
        outcome = self._final_check(designs)  # with a policy per design: each candidate's own
        if not self.shared:
            outcome.uncertainty["own_policies"] = self._save_own_policies(outcome.best_design)
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
        )
        s.phase = "done"
        self.checkpoint()
        # the store says "finished" once the caller's last step (`run_coadaptation(finishing=)`,
        # e.g. the CLI's video) is done too: an interrupt there leaves the run resumable
        self.emit("done")

    def _save_own_policies(self, best_design: np.ndarray) -> dict[str, str]:
        """Without a shared policy, the best and nominal designs' own policies go to the run
        folder as `OWN_POLICY_FILES` (the yardstick and sim-to-sim look them up by name)."""
        backend = self.get_backend()
        if not isinstance(backend, OwnPolicies):
            return {}
        (self.run_dir / "checkpoints").mkdir(exist_ok=True)
        for role, design in (("best", best_design), ("nominal", self.nominal)):
            self.count_training(
                backend.save_policy(
                    np.asarray(design, dtype=float), str(self.run_dir / OWN_POLICY_FILES[role])
                )
            )
        return dict(OWN_POLICY_FILES)

    def _final_fitness(self, designs: np.ndarray, block: int) -> RealFitness:
        """One scenario block of the final check; policies a backend trains first count as training."""
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

    def _final_check(self, designs: np.ndarray) -> FinalOutcome:
        """Paired blocks of fresh scenarios for the candidates and the nominal design (last)
        until the improvement is >= 4 standard errors (final_check.py)."""
        s, c = self.state, self.config
        check = final_check(
            self._final_fitness,
            designs,
            self.objectives,
            max_blocks=c.final_max_blocks,
            min_blocks=min(c.final_min_blocks, c.final_max_blocks),
            rule=self.cost_rule,
            fall_tolerance=c.fall_tolerance if len(self.objectives) == 1 else None,
            on_block=lambda b: self.emit(f"final check, scenario block {b}"),
        )
        fit = check.fit
        costs = np.asarray(fit.costs, dtype=float).reshape(len(designs), -1)
        s.counters["final_interactions"] += int(fit.interactions)
        s.counters["final_seconds"] += float(fit.seconds)
        # several objectives: the front is the non-dominated part of this real re-evaluation and the run returns its
        # design of lowest first cost; one: the lowest cost among candidates that do not fall more (else the nominal)
        front = check.front(designs, self.names) if len(self.objectives) > 1 else None
        i = int(front_rows(designs[:-1], costs[:-1])[0]) if front is not None else check.best
        best_design, best_costs = designs[i], costs[i]
        return FinalOutcome(
            best_design=best_design,
            best_costs=best_costs,
            nominal_costs=costs[-1],
            uncertainty=check.uncertainty(self.names),
            front=front,
            walking={"best": walking(fit, [i]), "nominal": walking(fit, [len(designs) - 1])},
        )
