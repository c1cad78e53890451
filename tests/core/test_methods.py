"""The method registry (`coadapt_core.methods`) and the BO baseline's backend
(`coadapt_core.coadapt.specialized`): every method defined once, the baseline's numbers
unchanged by becoming a backend, and its optimizer chosen by a declared capability."""

from __future__ import annotations

import ast
import json
from pathlib import Path

import numpy as np
import pytest
from coadapt_plugins.objectives.locomotion import TorqueObjective

from coadapt_core.coadapt.config_loading import make_config
from coadapt_core.coadapt.run import run_coadaptation
from coadapt_core.coadapt.specialized import OWN_POLICY_FILES, SpecializedPolicyBackend
from coadapt_core.errors import UserError
from coadapt_core.methods import (
    BACKEND_KINDS,
    METHOD_NAMES,
    METHODS,
    get_method,
    method_help,
    optimizer_for,
)
from coadapt_core.optimizer import Optimizer
from coadapt_core.results.recorders import read_evaluations
from tests.fakes.analytic import NOMINAL, SPACE, AnalyticBackend, optimum_of
from tests.test_core_plugin_neutral import string_constants

ROOT = Path(__file__).resolve().parents[2]

#: `bo-specialized` on the analytic backend (seed 0, 7 designs, 300 steps per policy, 8
#: agents x 20 steps), as the loop gave it while the baseline was still a branch of the loop
#: (commit de037f2): the backend must give the same counters, designs and costs
BEFORE = {
    "best_design": [0.5846051119125759, 0.5078781219076561],
    "best_cost": 1.0104109496158402,
    "nominal_cost": 1.3216875066133553,
    "improvement": 0.23551448843994827,
    "interactions": 3680,
    "train_interactions": 2400,
    "eval_interactions": 1120,
    "final_interactions": 160,
    "real_evaluations": 7,
    "surrogate_evaluations": 0,
    "designs_evaluated": 7,
    "batch_costs": [
        1.0104109496158402,
        1.3744722936201723,
        2.0618632951818174,
        1.6244439032998685,
        1.5816558528401512,
        1.6181875408916517,
        1.6667965309924038,
    ],
    "designs": [
        [0.5846051119125759, 0.5078781219076561],
        [1.1602997244598523, 0.842588140223364],
        [1.1643058075299733, 1.46124023602965],
        [1.3588378588212606, 0.8166137131071758],
        [1.052906621667419, 1.2122449985721413],
        [1.3766811508150498, 0.7151799646071582],
        [0.9492218635612647, 1.3369892227094273],
    ],
}
BO_RUN = {
    "method": "bo-specialized",
    "seed": 0,
    "bo_designs": 7,
    "specialized_train_steps": 300,
    "agents_per_design": 8,
    "eval_steps": 20,
    "population": 4,
    "store": "none",
    "logger": "none",
}


def bo_run(tmp_path, backend=AnalyticBackend, optimizer_cls=None, **overrides):
    config = make_config("smoke", overrides={**BO_RUN, "out": str(tmp_path), **overrides})
    return run_coadaptation(
        config,
        backend_factory=lambda seed: backend(seed),
        design_space=SPACE,
        nominal_design=NOMINAL,
        objectives=[TorqueObjective()],
        optimizer_cls=optimizer_cls,
    )


def test_bo_specialized_as_a_backend_gives_what_the_loop_branch_gave(tmp_path):
    """The optimisation is the branch's, design for design and cost for cost; the final stage
    is now the shared methods' paired final check (each design with its own policy, kept or
    trained again with the same seeds), and the best and nominal designs' policies are saved."""
    result = bo_run(tmp_path)
    s = result.summary
    for key in (
        "eval_interactions",
        "real_evaluations",
        "surrogate_evaluations",
        "designs_evaluated",
    ):
        assert s[key] == BEFORE[key], key
    np.testing.assert_allclose(s["best_design"], BEFORE["best_design"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        [b["best_cost"] for b in s["batches"]], BEFORE["batch_costs"], rtol=0, atol=1e-12
    )
    np.testing.assert_allclose(
        [e["design"] for e in read_evaluations(result.run_dir)], BEFORE["designs"], atol=1e-12
    )
    assert (
        s["optimizer"] == "bo"
        and s["pareto_front"] is None
        and s["surrogate_quality"]["rounds"] == []
    )
    # the final check: the 3 best real designs (costs 1.01, 1.37, 1.58) and the nominal design,
    # one block (the fake gives no per-scenario costs), 8 agents x 20 steps each
    assert s["final_interactions"] == 4 * 8 * 20 and s["final_blocks"] == 1
    # 7 proposals + the nominal design during the run; in the final check the policies of the
    # designs evaluated 1st and 2nd and of the nominal design had left the 4 kept, so 3 more
    assert s["train_interactions"] == 8 * 300 + 3 * 300
    assert (
        s["interactions"]
        == s["train_interactions"] + s["eval_interactions"] + s["final_interactions"]
    )
    # fresh scenarios (block 1): other noise than the rounds' block 0, the same order
    assert (
        s["best_cost"] != BEFORE["best_cost"] and abs(s["best_cost"] - BEFORE["best_cost"]) < 0.05
    )
    assert s["improvement"] == pytest.approx(1 - s["best_cost"] / s["nominal_cost"], abs=1e-12)
    assert s["own_policies"] == OWN_POLICY_FILES
    saved = {
        role: json.loads((result.run_dir / name).read_text())
        for role, name in OWN_POLICY_FILES.items()
    }
    assert saved["best"]["trained_low"] == s["best_design"] and saved["nominal"]["trained_low"] == [
        1.0,
        1.0,
    ]
    assert sorted(p.name for p in (result.run_dir / "checkpoints").iterdir()) == [
        "policy-best.pt",
        "policy-nominal.pt",
    ]


def test_each_design_gets_its_own_policy_seeded_by_the_design():
    calls = []

    class Recording(AnalyticBackend):
        def train(self, designs, steps, *, seed=0):
            calls.append((self.seed, seed, np.array(designs)))
            return super().train(designs, steps, seed=seed)

    backend = SpecializedPolicyBackend(Recording, train_steps=50, seed=3, keep=2)
    designs = np.array([[0.7, 0.9], [1.2, 0.6], [0.7, 0.9]])
    fit = backend.real_fitness(designs, [TorqueObjective()], agents=4, steps=10, seed=1)
    assert fit.costs.shape == (3, 1) and fit.buffer is None
    assert fit.interactions == 3 * 4 * 10  # rollouts only; training comes apart
    assert [t.steps for t in fit.training] == [
        50,
        50,
    ]  # the third is the first design again: its policy is kept
    assert [c[2].tolist() for c in calls] == [
        [d.tolist()] for d in designs[:2]
    ]  # each trained on its design alone
    assert fit.costs[0, 0] == fit.costs[2, 0]
    # a third design pushes out the least recently used (the second), which comes back
    # trained again with the same seeds, so the same policy, and pushes out the first
    backend.real_fitness(
        np.array([[1.4, 1.4], [1.2, 0.6]]), [TorqueObjective()], agents=4, steps=10, seed=1
    )
    assert len(calls) == 4 and calls[3][:2] == calls[1][:2] != calls[0][:2]
    assert backend.policy(designs[1])[1] == [] and len(calls) == 4  # kept
    assert [t.steps for t in backend.policy(designs[0])[1]] == [50] and calls[4][:2] == calls[0][:2]
    other = SpecializedPolicyBackend(Recording, train_steps=50, seed=4).policy_seeds(designs[0])
    assert other != calls[0][:2]  # another run, other policies


def test_per_scenario_falls_are_stacked_over_designs():
    """The capped rule sets a fallen scenario to the cap: the per-design policies' falls must
    reach the loop like the universal policy's."""
    from coadapt_core.fitness import RealFitness

    class Falling(AnalyticBackend):
        def real_fitness(self, designs, objectives, *, agents, steps, seed=0):
            fit = super().real_fitness(designs, objectives, agents=agents, steps=steps, seed=seed)
            per = np.repeat(fit.costs[:, None, :], agents, axis=1)
            falls = np.zeros((1, agents), dtype=bool)
            falls[0, : int(designs[0, 0] * 2)] = True
            return RealFitness(
                costs=fit.costs,
                buffer=None,
                interactions=fit.interactions,
                seconds=fit.seconds,
                per_scenario=per,
                scenario_falls=falls,
                fall_rate=falls.mean(axis=1),
            )

    fit = SpecializedPolicyBackend(Falling, train_steps=5).real_fitness(
        np.array([[0.6, 1.0], [1.4, 1.0]]), [TorqueObjective()], agents=4, steps=3
    )
    assert fit.scenario_falls.tolist() == [[True, False, False, False], [True, True, False, False]]
    assert fit.per_scenario.shape == (2, 4, 1) and fit.fall_rate.tolist() == [0.25, 0.5]


def test_no_core_module_spells_a_method_name():
    """Method names live in the registry only: a string constant (not a docstring) equal to
    a method name, or a comma list holding one, anywhere else in the core is a finding."""
    dirty = {}
    for path in sorted((ROOT / "coadapt_core").rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        if rel != "coadapt_core/methods.py" and (found := method_literals(path)):
            dirty[rel] = found
    assert not dirty, f"method names outside coadapt_core/methods.py: {dirty}"


def test_the_method_scan_finds_a_planted_name(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text(
        '"""Prose may name no-real."""\nMETHODS = ("ours", "x")\nDEFAULT = "a,no-retrain"\n'
        'help = "Method: see the registry"\n'
    )
    assert method_literals(bad) == ["2: 'ours'", "3: 'a,no-retrain'"]


def method_literals(path: Path) -> list[str]:
    return sorted(
        f"{node.lineno}: {node.value!r}"
        for node in string_constants(ast.parse(path.read_text()))
        if any(part.strip() in METHODS for part in node.value.split(","))
    )


def test_every_method_is_complete_and_told_apart_in_figures():
    assert METHOD_NAMES == (
        "ours",
        "no-surrogate",
        "no-real",
        "no-retrain",
        "bo-specialized",
    )  # the tables' order
    methods = list(METHODS.values())
    for attr in ("label", "marker", "color"):
        assert len({getattr(m, attr) for m in methods}) == len(methods), attr
    assert all(m.backend in BACKEND_KINDS and m.help for m in methods)
    assert all(m.name in method_help() for m in methods)
    with pytest.raises(UserError, match="method 'nope' is not one of ours, no-surrogate"):
        get_method("nope")


class SequentialRandom(Optimizer):
    """A third party's sequential optimizer: one uniform design per round."""

    name = "seq-random"
    sequential = True

    def __init__(self, space, **kwargs):
        super().__init__(space, **kwargs)
        self._rng = np.random.default_rng(self.seed)

    def _ask(self):
        return self.space.decode(self._rng.uniform(size=(1, self.space.dim)))

    def _tell(self, designs, costs):
        pass


class Registry:
    """Stands in for the plugin registry: these optimizers installed."""

    def __init__(self, *classes):
        self.classes = {c.name: c for c in classes}

    def names(self, kind):
        return sorted(self.classes)

    def get(self, kind, name):
        if name not in self.classes:
            raise UserError(f"unknown optimizer '{name}'", field="optimizer")
        return self.classes[name]


def bo_dir(tmp_path):
    return next(p for p in tmp_path.iterdir() if p.is_dir())


def test_the_baseline_takes_its_optimizer_by_the_declared_capability(monkeypatch):
    import coadapt_core.plugins as plugins

    class Swarm(SequentialRandom):
        name, sequential = "swarm", False

    class OtherSequential(SequentialRandom):
        name = "other-seq"

    monkeypatch.setattr(plugins, "get_registry", lambda: Registry(Swarm, SequentialRandom))
    assert optimizer_for("ours", "swarm") == "swarm"  # no need declared: untouched
    assert optimizer_for("bo-specialized", "swarm") == "seq-random"  # the one that declares it
    assert optimizer_for("bo-specialized", "seq-random") == "seq-random"
    monkeypatch.setattr(
        plugins, "get_registry", lambda: Registry(Swarm, SequentialRandom, OtherSequential)
    )
    assert optimizer_for("bo-specialized", "other-seq") == "other-seq"  # a third party's, as asked
    with pytest.raises(
        UserError,
        match=(
            r"needs an optimizer that declares sequential; 'swarm' does not "
            r".*other-seq, seq-random"
        ),
    ):
        optimizer_for("bo-specialized", "swarm")


def test_a_third_party_sequential_optimizer_runs_the_baseline(tmp_path):
    s = bo_run(tmp_path, optimizer_cls=SequentialRandom, bo_designs=12).summary
    assert s["optimizer"] == "seq-random"
    assert s["real_evaluations"] == 12 and s["designs_evaluated"] == 12
    # 12 policies + the nominal's, then those of the final check's 3 candidates and the
    # nominal design that were no longer kept (at most 4)
    assert s["train_interactions"] % 300 == 0 and 13 * 300 <= s["train_interactions"] <= 17 * 300
    best = np.array(s["best_design"])
    costs = sorted(b["best_cost"] for b in s["batches"])
    evaluated = [e["design"] for e in read_evaluations(bo_dir(tmp_path))]
    assert any(np.array_equal(best, d) for d in evaluated)
    assert costs[0] - 0.05 < s["best_cost"] < costs[2] + 0.05  # re-evaluated on fresh scenarios
    assert np.linalg.norm(best - optimum_of("torque")) < np.linalg.norm(
        NOMINAL - optimum_of("torque")
    )
