"""Conformance suite for co-adaptation backends (`coadapt_core.fitness.CoadaptationBackend`,
what the loop evaluates designs with). Supply a fixture `backend`: an instance, or the class
when building one is costly (the checks read its declared methods).

A backend that declares `surrogate_ensemble = True` must implement
`coadapt_core.fitness.SurrogateEnsemble` with the protocol's parameters; the loop relies on
that declaration instead of probing for methods."""

from __future__ import annotations

import inspect
from typing import Any

from coadapt_core.fitness import CoadaptationBackend, SurrogateEnsemble


def _protocol_methods(protocol: type) -> dict[str, inspect.Signature]:
    return {
        name: inspect.signature(fn)
        for name, fn in vars(protocol).items()
        if inspect.isfunction(fn) and not name.startswith("_")
    }


def _signature_problem(backend: Any, name: str, wanted: inspect.Signature) -> str | None:
    """Why `backend.name` cannot be called as the loop calls it: the protocol's positional
    parameters by position, its keyword-only ones by name (None: it can)."""
    method = getattr(backend, name, None)
    if not callable(method):
        return f"{name} is missing"
    try:
        got = inspect.signature(method)
    except (TypeError, ValueError):  # a builtin or C callable: nothing to read
        return None
    params = list(wanted.parameters.values())[1:]  # without self
    positional = [None] * sum(p.kind is p.POSITIONAL_OR_KEYWORD for p in params)
    keywords = {p.name: None for p in params if p.kind is p.KEYWORD_ONLY}
    if inspect.isclass(backend):  # an unbound function: its `self` too
        positional.insert(0, None)
    try:
        got.bind(*positional, **keywords)
    except TypeError as exc:
        return f"{name}{got} cannot be called as {name}{wanted} ({exc})"
    return None


def check_backend(backend: Any) -> list[str]:
    """Everything about `backend` (instance or class) the loop would trip over, one line
    each: a method of `CoadaptationBackend` missing or not callable as the loop calls it,
    and, when it declares `surrogate_ensemble`, the same for `SurrogateEnsemble`."""
    problems = []
    for name, signature in _protocol_methods(CoadaptationBackend).items():
        problem = _signature_problem(backend, name, signature)
        if problem:
            problems.append(f"CoadaptationBackend: {problem}")
    declared = getattr(backend, "surrogate_ensemble", False)
    if declared not in (True, False):
        problems.append(f"surrogate_ensemble must be True or False, got {declared!r}")
    if declared is True:
        for name, signature in _protocol_methods(SurrogateEnsemble).items():
            problem = _signature_problem(backend, name, signature)
            if problem:
                problems.append(
                    f"SurrogateEnsemble (declared by surrogate_ensemble = True): {problem}"
                )
    return problems


class BackendConformance:
    """Every backend: the loop's protocol methods, callable as the loop calls them; a
    declared surrogate ensemble implemented in full."""

    def test_implements_the_backend_protocol(self, backend: Any) -> None:
        problems = [p for p in check_backend(backend) if p.startswith("CoadaptationBackend")]
        assert not problems, "; ".join(problems)

    def test_a_declared_surrogate_ensemble_is_implemented(self, backend: Any) -> None:
        problems = [p for p in check_backend(backend) if not p.startswith("CoadaptationBackend")]
        assert not problems, "; ".join(problems)
