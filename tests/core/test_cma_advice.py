"""The CMA-ES example of docs/plugins.md, run exactly as printed: it passes the optimizer
conformance suite, and the same class without its private random stream (the advice before:
seed `cma` with `self.seed32` only) fails the save/reload check."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from coadapt_core.design_space import Continuous, DesignSpace
from coadapt_core.testing import OptimizerConformance

pytest.importorskip("cma")

DOCS = Path(__file__).resolve().parents[2] / "docs" / "plugins.md"


def documented_cmaes() -> type:
    text = DOCS.read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    source = next(b for b in blocks if "class CMAES(Optimizer)" in b)
    namespace: dict = {}
    exec(compile(source, str(DOCS), "exec"), namespace)  # the documentation's own code
    return namespace["CMAES"]


class TestDocumentedCMAES(OptimizerConformance):
    @pytest.fixture
    def optimizer_cls(self):
        return documented_cmaes()


def test_seeding_cma_alone_does_not_survive_a_reload():
    """Without `randn`, cma samples numpy's global generator: a restored copy and the
    original draw from one shared stream and their proposals part."""
    cls = documented_cmaes()

    class GlobalStream(cls):
        name = "cma-global"

        def _strategy(self, x0):
            import cma

            return cma.CMAEvolutionStrategy(
                x0,
                0.3,
                {
                    "popsize": self.population,
                    "bounds": [0.0, 1.0],
                    "verbose": -9,
                    "seed": self.seed32,
                },
            )

    space = DesignSpace([Continuous("a", 0.5, 1.5), Continuous("b", 0.5, 1.5)])

    def make():
        return GlobalStream(space, population=6, budget=6, seed=5)

    def cost(d):
        return ((d - 0.9) ** 2).sum(axis=1)

    a = make()
    for _ in range(2):
        d = a.ask()
        a.tell(d, cost(d))
    b = make()
    b.load_state_dict(json.loads(json.dumps(a.state_dict())))
    assert not np.array_equal(a.ask(), b.ask())
