"""The hybrid evaluation policy of the co-adaptation loop (Algorithm 4 line 14): which kind
each optimizer round is (a surrogate round with probability `surrogate_probability`, the
paper's fixed policy, or when the fitted ensemble agrees, `evaluation_policy: uncertainty`),
the surrogate's side of every round (fitting the ensemble to this policy's real rounds,
scoring a surrogate round, predicting a real round's designs before their costs are known)
and the quality records those predictions make (`summary.json`'s `surrogate_quality`).

The backend's surrogate is reached through its declared protocols only:
`CoadaptationBackend.surrogate_fitness` (the paper's estimator) and, when the backend
declares one, `SurrogateEnsemble` (coadapt_core.fitness).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from coadapt_core import surrogate_quality as sq
from coadapt_core.coadapt.config import CoadaptConfig
from coadapt_core.coadapt.state import LoopState
from coadapt_core.coadapt.trend import LinearTrend, trend_of_labels
from coadapt_core.fitness import (
    CoadaptationBackend,
    SurrogateEnsemble,
    surrogate_ensemble,
    surrogate_slope,
)
from coadapt_core.methods import Method
from coadapt_core.objective import Objective


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


class HybridPolicy:
    """The real/surrogate switch of a run and the surrogate's bookkeeping (module docstring).

    It reads and writes the run's `LoopState` (labels, buffer, counters, quality rounds) and
    draws from the loop's generator, so a resumed run decides as the first one would have;
    `backend()` is the loop's (built on first use), `seed_for(*parts)` its positional seeds."""

    def __init__(
        self,
        config: CoadaptConfig,
        method: Method,
        objectives: Sequence[Objective],
        state: LoopState,
        rng: np.random.Generator,
        backend: Callable[[], CoadaptationBackend],
        seed_for: Callable[..., int],
    ):
        self.config = config
        self.state = state
        self.rng = rng
        self.objectives = list(objectives)
        self.names = [o.name for o in self.objectives]
        self.backend = backend
        self.seed_for = seed_for
        forced = method.surrogate_probability  # a method of the comparison may force it
        self.surrogate_probability = config.surrogate_probability if forced is None else forced
        self.uncertainty = config.evaluation_policy == "uncertainty" and forced is None
        self._fitted_for: tuple[int, int, int] | None = (
            None  # (outer, labels, buffer) the backend's fit is for
        )
        self._pending: tuple[int, np.ndarray] | None = (
            None  # (inner, ensemble's costs) of a trusted round
        )
        self._judging = (
            True  # whether this real round's surrogate error is measured (before_real_round)
        )

    def forget_fit(self) -> None:
        """A new backend or a new policy: the ensemble must be fitted again."""
        self._fitted_for = None

    def ensemble(self) -> SurrogateEnsemble | None:
        return surrogate_ensemble(self.backend())

    def real_share(self, real_rounds: int, surrogate_rounds: int) -> float:
        """The share of rounds still to come that will be real, for the ETA: 1 - p under the
        fixed policy, the share seen so far under the uncertainty policy (`real_rounds` > 0)."""
        if self.uncertainty:
            return real_rounds / (real_rounds + surrogate_rounds)
        return 1.0 - self.surrogate_probability

    # -- which kind of round ---------------------------------------------------------------
    def choose_kind(self, designs: np.ndarray | None = None) -> tuple[str, float | None]:
        """Hybrid evaluation (Algorithm 4 line 14): surrogate with probability
        `surrogate_probability` (the paper's w), else real. The draw is made every round so
        the random stream does not depend on the buffer; the surrogate needs an evaluation
        buffer from the current policy, so without one the round is real (the first of each
        outer iteration, unless training filled it).

        `evaluation_policy: uncertainty` (method ours only; beyond the paper): the fitted
        ensemble predicts the round's designs, and the round is a surrogate round when its
        members agree — their spread over the designs' spread (`spread_ratio`) at most
        `uncertainty_threshold` — else real. No fit (no real round of this policy yet, or a
        backend without an ensemble): real. Returns the kind and the spread ratio the
        uncertainty policy judged (None when it judged none)."""
        s = self.state
        draw = self.rng.random()
        if s.buffer is None or s.buffer_outer != s.outer:
            return "real", None
        if s.no_critic and not self.ensure_fitted():
            # an objective without a pseudo-critic in the starting policy: the fit to this
            # policy's real rounds stands in for it, or the round is real
            # (starting_policy.objectives_without_critic)
            return "real", None
        if self.uncertainty and designs is not None:
            return self._agreed_kind(designs)
        return ("surrogate" if draw < self.surrogate_probability else "real"), None

    def _agreed_kind(self, designs: np.ndarray) -> tuple[str, float | None]:
        """The uncertainty policy: a surrogate round when the fitted members agree."""
        s, c = self.state, self.config
        ensemble = self.ensemble()
        if ensemble is None or not self.ensure_fitted():
            return "real", None
        t0 = time.perf_counter()
        members = ensemble.surrogate_members(
            designs,
            self.objectives,
            s.buffer,
            samples=c.surrogate_samples,
            seed=self.seed_for(3, s.outer, s.inner),
        )
        s.counters["surrogate_seconds"] += time.perf_counter() - t0
        if members is None:
            return "real", None
        members = np.asarray(members, dtype=float).reshape(-1, len(designs), len(self.objectives))
        spread = spread_ratio(members)
        if spread <= c.uncertainty_threshold:
            self._pending = (s.inner, members.mean(axis=0))
            return "surrogate", spread
        return "real", spread

    def ensure_fitted(self) -> bool:
        """Fit the backend's ensemble to this policy's real rounds (`LoopState.labels`)
        unless its fit already covers them (also after a resume: the fit is a function of the
        labels, the buffer and the seed). False when there is nothing to fit or no ensemble."""
        s, c = self.state, self.config
        ensemble = self.ensemble()
        if (
            not c.fit_surrogate
            or ensemble is None
            or not s.labels
            or s.buffer is None
            or s.buffer_outer != s.outer
        ):
            return False
        key = (s.outer, len(s.labels), s.buffer_serial)
        if self._fitted_for != key:
            t0 = time.perf_counter()
            designs = np.concatenate(
                [np.asarray(item["designs"], dtype=float) for item in s.labels]
            )
            costs = np.concatenate([np.asarray(item["costs"], dtype=float) for item in s.labels])
            ensemble.fit_surrogate(
                designs,
                costs,
                self.objectives,
                s.buffer,
                seed=self.seed_for(6, s.outer, len(s.labels)),
            )
            s.counters["surrogate_seconds"] += time.perf_counter() - t0
            self._fitted_for = key
        return True

    # -- the surrogate's side of a round ---------------------------------------------------
    def surrogate_round(self, designs: np.ndarray, seed: int) -> tuple[np.ndarray, float]:
        """costs [P, M] and seconds of a surrogate round (the ensemble's prediction when the
        uncertainty policy just made it, else the backend's surrogate after any fit)."""
        s, c = self.state, self.config
        t0 = time.perf_counter()
        # the round's seconds include a fit it needs: counted once (ensure_fitted counts it too)
        counted = s.counters["surrogate_seconds"]
        if (
            self._pending is not None and self._pending[0] == s.inner
        ):  # the ensemble's, just computed
            predicted = self._pending[1]
        elif (trend := self.trend()) is not None:
            predicted = trend.predict(designs)
        else:
            self.ensure_fitted()
            predicted = self.backend().surrogate_fitness(
                designs, self.objectives, s.buffer, samples=c.surrogate_samples, seed=seed
            )
        self._pending = None
        seconds = time.perf_counter() - t0
        s.counters["surrogate_seconds"] = counted + seconds
        s.counters["eval_seconds"] += seconds
        s.counters["surrogate_evaluations"] += 1
        return np.asarray(predicted, dtype=float).reshape(len(designs), -1), seconds

    def trend(self) -> LinearTrend | None:
        """With `surrogate_trend`: the plane through this policy's real rounds (None without
        enough of them: the backend's surrogate stands in)."""
        return trend_of_labels(self.state.labels) if self.config.surrogate_trend else None

    def before_real_round(self) -> tuple[bool, bool, Any]:
        """(eligible, fitted, states) before a real round's rollouts: whether a surrogate
        round would have been allowed here (a real round of this policy came before), the
        ensemble fitted for it, and the buffer it would have used.

        Whether the round is judged at all (`judge_real_round`) is decided here too: the
        surrogate's error costs no fit of its own unless `surrogate_error_fits` asks for one.
        Without it a real round is judged when the surrogate a surrogate round here would use
        needs no new fit: the paper's estimator (`fit_surrogate` off), or a fit that already
        covers this round's labels and buffer (the previous round of this policy was a
        surrogate round, or the uncertainty policy fitted for this round's decision). That
        is read from the run's state, so a resumed run judges the rounds the first one would."""
        s, c = self.state, self.config
        eligible = s.buffer is not None and s.buffer_outer == s.outer
        self._judging = c.measure_surrogate_error
        if c.surrogate_trend and self.trend() is not None:  # the plane costs no fit: judged
            self._judging = self._judging and eligible
            return eligible, False, s.buffer
        if c.fit_surrogate and self.ensemble() is not None and not c.surrogate_error_fits:
            self._judging = self._judging and eligible and self._fit_covers_round()
        fitted = eligible and self._judging and self.ensure_fitted()
        return eligible, fitted, s.buffer

    def _fit_covers_round(self) -> bool:
        """The ensemble's fit for this round is made already, or would be made for free (no
        real round since this policy's last surrogate round)."""
        s = self.state
        if self._fitted_for == (s.outer, len(s.labels), s.buffer_serial):
            return True
        last = s.batches[-1] if s.batches else None
        return (
            bool(s.labels)
            and last is not None
            and last["outer"] == s.outer
            and last["kind"] != "real"
        )

    def judge_real_round(
        self,
        designs: np.ndarray,
        costs: np.ndarray,
        states: Any,
        *,
        eligible: bool,
        fitted: bool,
        seed: int,
    ) -> np.ndarray | None:
        """The surrogate's errors [P, M] on a real round: its prediction, made before this
        round's costs are known (the first round of a policy: the paper's estimator on its
        own buffer, marked not eligible), recorded with its quality figures. None when
        `before_real_round` decided not to judge the round."""
        s, c = self.state, self.config
        if not self._judging:
            return None
        t0 = time.perf_counter()
        ensemble = self.ensemble() if fitted else None
        members = None
        trend = self.trend() if eligible else None
        if trend is not None:  # the plane a surrogate round here would have used
            ensemble = None
            predicted = trend.predict(designs)
        elif ensemble is not None:  # the members too: their spread ratio is recorded
            members = ensemble.surrogate_members(
                designs, self.objectives, states, samples=c.surrogate_samples, seed=seed
            )
        if members is not None:
            members = np.asarray(members, dtype=float).reshape(-1, *costs.shape)
            predicted = members.mean(axis=0)
        elif trend is None:
            predicted = self.backend().surrogate_fitness(
                designs, self.objectives, states, samples=c.surrogate_samples, seed=seed
            )
        s.counters["surrogate_seconds"] += time.perf_counter() - t0
        predicted = np.asarray(predicted, dtype=float).reshape(costs.shape)
        self.record_quality(
            predicted,
            costs,
            eligible=eligible,
            fitted=fitted,
            spread=None if members is None else spread_ratio(members),
            trend=trend is not None,
        )
        return predicted - costs

    # -- the surrogate's gradient, for an optimizer that follows it -----------------------
    def slope_oracle(self) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]] | None:
        """designs [K, D] -> (costs [K], gradients [K, D]) of the surrogate a surrogate round
        would use now (the ensemble fitted to this policy's real rounds when there is one),
        on a fixed bank of states of the last rollouts (`surrogate_samples` of them, drawn by
        the round's seed); None without a buffer of this policy or a backend that offers no
        `SurrogateSlope` (the optimizer then works without it)."""
        s, c = self.state, self.config
        backend = surrogate_slope(self.backend())
        if backend is None or s.buffer is None or s.buffer_outer != s.outer:
            return None
        self.ensure_fitted()
        buffer, seed = s.buffer, self.seed_for(7, s.outer, s.inner)

        def oracle(designs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            t0 = time.perf_counter()
            costs, grads = backend.surrogate_slope(
                designs, self.objectives[:1], buffer, samples=c.surrogate_samples, seed=seed
            )
            s.counters["surrogate_seconds"] += time.perf_counter() - t0
            return np.asarray(costs, dtype=float)[:, 0], np.asarray(grads, dtype=float)[:, 0]

        return oracle

    # -- quality records -------------------------------------------------------------------
    def record_quality(
        self,
        predicted: np.ndarray,
        costs: np.ndarray,
        *,
        eligible: bool,
        fitted: bool,
        spread: float | None = None,
        trend: bool = False,
    ) -> None:
        """One entry of `surrogate_quality.rounds`: the round's (surrogate, real) pairs per
        objective and their figures (coadapt_core/surrogate_quality.py), and the fitted
        ensemble's spread ratio on the round (what the uncertainty policy would have seen)."""
        s = self.state
        entry: dict[str, Any] = {
            "outer": s.outer,
            "inner": s.inner,
            "eligible": bool(eligible),
            "estimator": "trend" if trend else ("fitted" if fitted else "paper"),
            "spread_ratio": spread,
            "objectives": {},
        }
        for j, name in enumerate(self.names):
            pairs = {"surrogate": predicted[:, j].tolist(), "real": costs[:, j].tolist()}
            entry["objectives"][name] = {**quality_of(pairs["surrogate"], pairs["real"]), **pairs}
        s.quality_rounds.append(sq.clean(entry))
        from coadapt_core import tracking

        tracking.log_values(
            "surrogate_quality",
            {
                f"{name}_{m}": q[m]
                for name, q in entry["objectives"].items()
                for m in sq.METRICS
                if isinstance(q.get(m), float) and np.isfinite(q[m])
            }
            | {"eligible": float(eligible)},
            len(s.quality_rounds),
        )

    def quality_summary(self) -> dict[str, Any]:
        """summary.json's `surrogate_quality`: pooled over the eligible rounds (those where a
        surrogate round was allowed: what the surrogate rounds of the run relied on), the
        first objective's figures in `pooled`, every objective's in `by_objective`."""
        rounds = self.state.quality_rounds
        used = [r for r in rounds if r["eligible"]]
        by_objective = {}
        for name in self.names:
            pairs = [
                {
                    "surrogate": _floats(r["objectives"][name]["surrogate"]),
                    "real": _floats(r["objectives"][name]["real"]),
                }
                for r in used
                if name in r["objectives"]
            ]
            by_objective[name] = sq.clean(sq.pooled(pairs))
        if self.names:  # the pooled pairs' noise ceiling, where every judged round kept its SEs
            first = [r["objectives"].get(self.names[0]) or {} for r in used]
            if first and all("se" in q for q in first):
                by_objective[self.names[0]] = sq.with_ceiling(
                    by_objective[self.names[0]],
                    [x for q in first for x in q["real"]],
                    [x for q in first for x in q["se"]],
                )
        brief = [
            {k: v for k, v in r.items() if k != "objectives"}
            | {
                "objectives": {
                    n: {m: q.get(m) for m in (*sq.METRICS, "n")}
                    | {m: q[m] for m in sq.CEILING_FIGURES if m in q}
                    for n, q in r["objectives"].items()
                }
            }
            for r in rounds
        ]
        return {
            "pooled": by_objective[self.names[0]] if self.names else {},
            "by_objective": by_objective,
            "rounds": brief,
            "estimator": "trend"
            if self.config.surrogate_trend
            else ("fitted" if self.config.fit_surrogate else "paper"),
            "definition": "over eligible real rounds (a real round of the same policy came "
            "before); relative error (surrogate - real) / |real|; top_k_regret: (best real "
            "cost among the surrogate's "
            f"{sq.TOP_K} cheapest - best real cost) / |best real cost|, mean over rounds",
        }
