"""The methods of the paper's comparison (its Tables 6-7), each defined once: its name (what
`coadapt run --method` and the grid take), its label and marks in tables and figures, its
help line, the switches the co-adaptation loop runs it with, the backend it evaluates
designs with and what it needs from its optimizer.

Config validation, `coadapt run --help`, the grid and the report all read this table; no
other module of the core spells a method's name (tests/core/test_methods.py checks).
"""

from __future__ import annotations

from dataclasses import dataclass

from coadapt_core.errors import UserError
from coadapt_core.optimizer import Optimizer


@dataclass(frozen=True)
class BackendKind:
    """How a method's backend learns the policies its designs are evaluated with."""

    name: str
    #: one policy trained on the K designs sampled from the range (Algorithm 4 lines 10-11),
    #: shared by every design of the search and carrying the pseudo-critics of the surrogate.
    #: False: nothing is trained up front, each design evaluated gets a policy of its own
    #: (its training is part of its real evaluation), there is no surrogate, and a design's
    #: real cost is final (the final check evaluates only the nominal design, with its own policy)
    shared_policy: bool
    description: str


BACKEND_KINDS: dict[str, BackendKind] = {
    kind.name: kind
    for kind in (
        BackendKind("universal", True, "the universal policy pi(a | o, xi) and its pseudo-critics"),
        BackendKind(
            "specialized",
            False,
            "a policy trained on each evaluated design alone (coadapt_core.coadapt.specialized)",
        ),
    )
}


@dataclass(frozen=True)
class Method:
    """One method of the comparison and everything that distinguishes it."""

    name: str
    label: str  # row label of the tables, legend of the figures
    help: str  # one line: `coadapt run --help`, docs
    marker: str  # matplotlib marker in the figures
    color: str  # matplotlib colour in the figures
    retrain: bool = True  # retrain the shared policy every outer iteration on the new range
    narrow: bool = True  # narrow the range around the final particles
    surrogate_probability: float | None = (
        None  # None: the config's `surrogate_probability` (w); else forced
    )
    # take R_eval from the training rollouts when the backend offers it (no-real only: the
    # other methods fill it with the first, real, round of each outer iteration, as in the
    # paper where R_eval comes from Algorithm 2)
    buffer_from_training: bool = False
    backend: str = "universal"  # a key of BACKEND_KINDS
    #: the config setting holding the number of optimizer rounds of the whole search (None:
    #: `optimizer_iterations` per outer iteration)
    rounds_setting: str | None = None
    #: an `Optimizer` capability flag the method needs (e.g. `sequential`: one design per
    #: round, as a policy is trained for every design); None: any optimizer
    optimizer_needs: str | None = None

    @property
    def backend_kind(self) -> BackendKind:
        return BACKEND_KINDS[self.backend]


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method(
            "ours",
            "Ours",
            "universal policy, hybrid real/surrogate fitness, narrowing (the paper's method)",
            marker="o",
            color="tab:red",
        ),
        Method(
            "no-surrogate",
            "Ours w/o Surrogate",
            "as ours, every optimizer round evaluated for real",
            marker="s",
            color="tab:blue",
            surrogate_probability=0.0,
        ),
        Method(
            "no-real",
            "Ours w/o Real",
            "as ours, every optimizer round scored by the surrogate",
            marker="^",
            color="tab:green",
            surrogate_probability=1.0,
            buffer_from_training=True,
        ),
        Method(
            "no-retrain",
            "Ours w/o Retraining",
            "one universal policy over the full range, trained once; N x J real rounds in one "
            "search",
            marker="D",
            color="tab:purple",
            retrain=False,
            narrow=False,
            surrogate_probability=0.0,
        ),
        Method(
            "bo-specialized",
            "BO",
            "baseline: a sequential optimizer proposing bo_designs designs, each with a policy "
            "trained for it alone",
            marker="P",
            color="tab:orange",
            retrain=False,
            narrow=False,
            surrogate_probability=0.0,
            backend="specialized",
            rounds_setting="bo_designs",
            optimizer_needs="sequential",
        ),
    )
}
#: `--method` choices, in the tables' order
METHOD_NAMES: tuple[str, ...] = tuple(METHODS)
DEFAULT_METHOD: str = METHOD_NAMES[0]

for _m in METHODS.values():  # a typo in the table fails at import, not in a run
    assert _m.backend in BACKEND_KINDS, _m
    assert _m.optimizer_needs is None or isinstance(
        getattr(Optimizer, _m.optimizer_needs, None), bool
    ), _m


def get_method(name: str) -> Method:
    """The method called `name`; anything else is a one-line user error listing the choices."""
    if name not in METHODS:
        raise UserError(f"method '{name}' is not one of {', '.join(METHOD_NAMES)}", field="method")
    return METHODS[name]


def method_help() -> str:
    """The `--method` help: every method with its line."""
    return "Method: " + "; ".join(f"{m.name}: {m.help}" for m in METHODS.values()) + "."


def optimizer_for(method: str, optimizer: str) -> str:
    """The optimizer a run of `method` searches with: `optimizer`, unless the method needs a
    capability (`Method.optimizer_needs`) that optimizer does not declare; then the one
    installed optimizer that declares it (for a method without a shared policy, one that does
    not follow the surrogate's slope: there is no surrogate). None or several such: a user
    error naming them."""
    need = get_method(method).optimizer_needs
    if need is None:
        return optimizer
    from coadapt_core.optimizer import follows_surrogate_slope
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    classes = {n: registry.get("optimizer", n) for n in registry.names("optimizer")}
    if getattr(classes.get(optimizer), need, False):
        return optimizer
    able = [n for n, cls in classes.items() if getattr(cls, need, False)]
    if not get_method(method).backend_kind.shared_policy:
        # no shared policy, no surrogate: an optimizer that follows its slope is no choice
        able = [n for n in able if not follows_surrogate_slope(classes[n])]
    if len(able) == 1:
        return able[0]
    raise UserError(
        f"method '{method}' needs an optimizer that declares {need}; '{optimizer}' does not "
        f"(installed that do: {', '.join(able) or 'none'})",
        field="optimizer",
    )


__all__ = [
    "BACKEND_KINDS",
    "DEFAULT_METHOD",
    "METHODS",
    "METHOD_NAMES",
    "BackendKind",
    "Method",
    "get_method",
    "method_help",
    "optimizer_for",
]
