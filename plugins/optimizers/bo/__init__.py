"""Bayesian optimisation with optuna (TPE by default, GP optional), one design per ask/tell
round through `study.ask()`/`study.tell()`. The baseline of the paper's Table 7 pairs it with
a specialised policy per proposed design (`--method bo-specialized`)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

from coadapt_plugins.optimizers._common import finite_costs

from coadapt_core import hookimpl
from coadapt_core.design_space import Continuous, DesignSpace
from coadapt_core.errors import UserError
from coadapt_core.optimizer import Optimizer
from coadapt_core.options import PluginOption

if TYPE_CHECKING:  # numpy is imported where it is used: listing the plugins loads none
    import numpy as np

#: the coadapt plugin API version this plugin is written for (docs/plugins.md#migration)
COADAPT_PLUGIN_API = "2.0"

SAMPLERS = ("tpe", "gp")


class BOOptimizer(Optimizer):
    """Sequential BO over mixed spaces: continuous variables via float distributions,
    discrete ones as categorical choices.

    Options (`option_specs`): sampler ('tpe' | 'gp'), n_startup_trials (random trials before
    the model, 8), storage (an optuna storage URL, e.g. 'sqlite:///runs/x/results.db', so the
    study lives in the run's database; default in memory), study_name (default
    'coadapt-bo-<seed>'). `initial_designs` ([n, dim]) are enqueued as the first trials. The
    samplers get `seed32` (optuna's samplers take 32-bit seeds).
    """

    name: ClassVar[str] = "bo"
    description: ClassVar[str] = "Bayesian optimisation (optuna TPE or GP), one design at a time"
    supports_mixed: ClassVar[bool] = True
    sequential: ClassVar[bool] = True
    option_specs: ClassVar[tuple] = (
        PluginOption(
            "sampler",
            "str",
            "tpe",
            "optuna sampler: tpe or gp",
            choices=SAMPLERS,
            alias="bo_sampler",
        ),
        PluginOption(
            "n_startup_trials", "int", 8, "random trials before the model is used", minimum=1
        ),
        PluginOption(
            "storage",
            "str",
            None,
            "optuna storage URL for the study (default: in memory)",
            alias="bo_storage",
            from_run="store_url",
        ),
        PluginOption(
            "study_name",
            "str",
            None,
            "name of the optuna study (default: coadapt-bo-<seed>)",
            from_run="run_name",
        ),
    )

    def __init__(self, space: DesignSpace, **kwargs: Any):
        super().__init__(space, **kwargs)
        o = self.options
        self.sampler_name = o["sampler"]
        self.n_startup_trials = o["n_startup_trials"]
        self.storage = o["storage"] or None
        self.study_name = o["study_name"] or f"coadapt-bo-{self.seed}"
        self._initial = self.initial_designs
        self._study = None  # made at the first ask (or rebuilt by load_state_dict)
        self._trial = None

    def _ensure_study(self):
        if self._study is None:
            self._make_study(load_if_exists=False)
            if self._initial is not None:
                for design in self._initial:
                    self._study.enqueue_trial(self._params(design))
        return self._study

    # -- optuna plumbing -------------------------------------------------------------------
    def _sampler(self):
        import optuna

        if self.sampler_name == "gp":
            return optuna.samplers.GPSampler(
                seed=self.seed32, n_startup_trials=self.n_startup_trials
            )
        return optuna.samplers.TPESampler(seed=self.seed32, n_startup_trials=self.n_startup_trials)

    def _make_study(self, *, load_if_exists: bool, sampler=None) -> None:
        import optuna

        optuna.logging.set_verbosity(optuna.logging.WARNING)
        try:
            self._study = optuna.create_study(
                storage=self.storage,
                study_name=self.study_name,
                sampler=sampler or self._sampler(),
                direction="minimize",
                load_if_exists=load_if_exists,
            )
        except optuna.exceptions.DuplicatedStudyError:
            raise UserError(
                f"an optuna study named '{self.study_name}' already exists in {self.storage}; "
                "pick another study name or storage",
                field="bo_storage",
            ) from None

    def _distributions(self) -> dict:
        from optuna.distributions import CategoricalDistribution, FloatDistribution

        out = {}
        for var in self.space.variables:
            if isinstance(var, Continuous):
                out[var.name] = FloatDistribution(var.low, max(var.high, var.low + 1e-12))
            else:
                out[var.name] = CategoricalDistribution(list(var.choices))
        return out

    def _params(self, design: np.ndarray) -> dict:
        return {name: float(value) for name, value in zip(self.space.names, design, strict=True)}

    # -- ask / tell ------------------------------------------------------------------------
    def _ask(self) -> np.ndarray:
        import numpy as np

        self._trial = self._ensure_study().ask(self._distributions())
        return np.array([[float(self._trial.params[n]) for n in self.space.names]])  # [1, dim]

    def _tell(self, designs: np.ndarray, costs: np.ndarray) -> None:
        if self._trial is None:
            raise RuntimeError("tell() without a preceding ask()")
        self._study.tell(self._trial, float(finite_costs(costs)[0]))
        self._trial = None

    def final_population(self) -> np.ndarray:
        """Every design tried so far (BO has no swarm to narrow around)."""
        import numpy as np

        trials = [t for t in self._ensure_study().trials if t.value is not None]
        if not trials:
            return super().final_population()
        return np.array([[float(t.params[n]) for n in self.space.names] for t in trials])

    # -- state as data: the study is rebuilt from the recorded rounds --------------------
    def _restore(self, state: dict[str, Any], rounds: list) -> None:
        """Replay the told rounds into a fresh in-memory study with the same seeded sampler,
        so the sampler's random stream is where an uninterrupted run's would be. A study kept
        in a database (`storage`) already holds those trials: it is reopened with the
        replayed sampler instead of being told them twice."""
        storage = self.storage
        self.storage = None
        try:
            super()._restore(state, rounds)
        finally:
            self.storage = storage
        if storage is not None:
            from optuna.search_space import IntersectionSearchSpace

            # the replayed sampler's random streams (and model caches) go to a fresh sampler;
            # only its per-study search-space cache stays the fresh one's (nothing told yet:
            # the fresh sampler is where the run was)
            sampler = self._sampler()
            if self._study is not None:
                for key, value in vars(self._study.sampler).items():
                    if not isinstance(value, IntersectionSearchSpace):
                        setattr(sampler, key, value)
            self._study = None
            self._make_study(load_if_exists=True, sampler=sampler)
            if self._initial is not None and not self._study.trials:  # stopped before its first ask
                for design in self._initial:
                    self._study.enqueue_trial(self._params(design))


@hookimpl
def coadapt_register_optimizers() -> list[type[Optimizer]]:
    return [BOOptimizer]
