"""The optimizer of one outer iteration (Algorithm 4 lines 12-21): its constructor arguments
kept as data in the state (`LoopState.optimizer_init`, so a resumed run rebuilds the same
optimizer and loads its `state_dict()`), and the options it declares `from_run` filled from
the run.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from coadapt_core.design_space import DesignSpace
from coadapt_core.fitness import RunRecorder
from coadapt_core.optimizer import Optimizer
from coadapt_core.options import fill_from_run


def optimizer_init(
    space: DesignSpace,
    *,
    population: int,
    budget: int,
    seed: int,
    num_objectives: int,
    initial_designs: np.ndarray | None,
    options: dict[str, Any],
) -> dict[str, Any]:
    """The optimizer's constructor arguments as data (`LoopState.optimizer_init`)."""
    return {
        "space": space.to_dict(),
        "population": population,
        "budget": budget,
        "seed": seed,
        "num_objectives": num_objectives,
        "initial_designs": initial_designs,
        "options": options,
    }


def make_optimizer(optimizer_cls: type[Optimizer], init: dict[str, Any]) -> Optimizer:
    """The optimizer from its constructor arguments as data (`optimizer_init`)."""
    return optimizer_cls(
        DesignSpace.from_dict(init["space"]),
        population=init["population"],
        budget=init["budget"],
        seed=init["seed"],
        num_objectives=init["num_objectives"],
        initial_designs=init["initial_designs"],
        **init["options"],
    )


def optimizer_options(
    optimizer_cls: type[Optimizer],
    options: dict[str, Any],
    *,
    run_name: str,
    recorder: RunRecorder,
    start: np.ndarray | None = None,
) -> dict[str, Any]:
    """The run's `optimizer_options`, as the optimizer plugin declared them (checked
    against its `option_specs` by the optimizer's constructor), with the options it
    declares `from_run` filled where the run leaves them unset (`coadapt_core.options`):
    a study kept under `run_name` (`<run id>-outer<k>`) in the run's results store, where a
    study browser reads it and no two runs of a grid share a name; and the design a descent
    starts from (`start`)."""
    url = getattr(recorder, "url", None)
    facts = {
        "run_name": run_name,
        "store_url": url if isinstance(url, str) and "://" in url else None,
        "start_design": None if start is None else ",".join(f"{v:.9g}" for v in start),
    }
    return fill_from_run(getattr(optimizer_cls, "option_specs", ()), options, facts)
