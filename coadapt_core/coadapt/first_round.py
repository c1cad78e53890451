"""The optimizer's first round: the designs it is built with (`initial_designs`, the ones the
policy is trained on, Algorithm 4 line 10) must be the designs its first `ask` returns. A
plugin written before they were a constructor argument ignores them; the run says so, once."""

from __future__ import annotations

import sys

import numpy as np

from coadapt_core.design_space import DesignSpace
from coadapt_core.optimizer import Optimizer


def initial_designs_note(
    optimizer_cls: type[Optimizer],
    space: DesignSpace,
    population: int,
    num_objectives: int,
    options: dict,
) -> str | None:
    """A warning when the optimizer's first `ask` does not return the `initial_designs` it was
    built with (a plugin written before they were a constructor argument ignores them: the
    run would still finish, its first round not the designs the policy was trained on). One
    throwaway optimizer on sampled designs, before any training; one with options filled from
    the run (a study kept in the run's store, `from_run`) is not probed: the loop checks its
    real first round. None when it complies or cannot be probed (its own errors are reported
    when the run builds it)."""
    initial = space.sample(population, np.random.default_rng(0))
    try:
        first = optimizer_cls(
            space,
            population=population,
            budget=2,
            seed=1,
            num_objectives=num_objectives,
            initial_designs=initial,
            **options,
        ).ask()
    except Exception:
        return None
    return first_round_note(optimizer_cls.name, initial, first)


def note_first_round(
    notes: list[str], optimizer_cls: type[Optimizer], initial: np.ndarray, designs: np.ndarray
) -> None:
    """Say (once per run: stderr and `notes`, the summary's) when the optimizer's first round
    `designs` is not the `initial` designs it was built with (`initial_designs_note` probes
    for it before training where it can)."""
    rows = 1 if optimizer_cls.sequential else len(initial)
    note = first_round_note(optimizer_cls.name, initial[:rows], designs)
    if note is not None and not any(n.startswith(f"warning: {note[:40]}") for n in notes):
        notes.append(f"warning: {note}")
        print(f"warning: {note}", file=sys.stderr)


def first_round_note(name: str, initial: np.ndarray, first: np.ndarray) -> str | None:
    """The warning (without its 'warning: ' prefix) when an optimizer's first proposals
    `first` are not the `initial` designs it was given; None when they are."""
    first = np.atleast_2d(np.asarray(first, dtype=float))
    initial = np.atleast_2d(np.asarray(initial, dtype=float))
    if first.shape == initial.shape and np.allclose(first, initial, atol=1e-9):
        return None
    return (
        f"optimizer '{name}' ignores `initial_designs`: its first round is not the {len(initial)} "
        "designs the policy is trained on (Algorithm 4 line 10), so this run does not follow the "
        "paper; the plugin needs updating (docs/plugins.md#migration; OptimizerConformance checks "
        "it)"
    )


def first_round_warnings(
    optimizer_cls: type[Optimizer],
    space: DesignSpace,
    population: int,
    num_objectives: int,
    options: dict,
) -> list[str]:
    """The run's start-up warning (a list of at most one line) when the optimizer would not
    start from the designs the policy is trained on (Algorithm 4 line 10): a throwaway copy
    is asked now (`initial_designs_note`), unless building one has side effects (a study kept
    in the run's store: options the plugin declares `from_run`); the loop checks the real
    first round too (`note_first_round`)."""
    if any(spec.from_run for spec in getattr(optimizer_cls, "option_specs", ())):
        return []
    if optimizer_cls.sequential and population != 1:
        return []
    note = initial_designs_note(optimizer_cls, space, population, num_objectives, options)
    return [f"warning: {note}"] if note else []
