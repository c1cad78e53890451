"""The common yardstick: every run's best design and its nominal design evaluated with the
run's own policy on one common scenario set, stored as rows the report and an export carry;
the stored figures are `compare_designs` of the same per-scenario costs, and a run that has
them is not evaluated again."""

from __future__ import annotations

import numpy as np
import pytest

from coadapt_core.analysis.facts import yardstick_improvement
from coadapt_core.costs import CostRule, compare_designs
from coadapt_core.experiments.yardstick import COMMON_SEED, yardstick_rows, yardstick_runs
from coadapt_core.fitness import RealFitness
from coadapt_core.plugins import get_registry
from coadapt_core.results import SqliteRecorder
from coadapt_core.scenarios.seeds import scenario_seed
from tests.core.test_report import record_run


class ScenarioBackend:
    """Per-scenario costs drawn from the call's seed (so blocks differ and repeat), the best
    design about 20 % cheaper than nominal, the first design falling in every 10th scenario."""

    def __init__(self):
        self.seeds = []

    def real_fitness(self, designs, objectives, *, agents, steps, seed=0):
        self.seeds.append(seed)
        rng = np.random.default_rng(seed)
        base = rng.uniform(1.0, 2.0, size=(agents, len(objectives)))
        per = np.stack([base * (0.8 if k == 0 else 1.0) for k in range(len(designs))])
        falls = np.zeros((len(designs), agents), dtype=bool)
        falls[0, ::10] = True
        per[0, ::10] *= 5.0
        return RealFitness(
            costs=per.mean(axis=1),
            buffer=None,
            interactions=len(designs) * agents * steps,
            seconds=0.1,
            per_scenario=per,
            scenario_falls=falls,
        )


@pytest.fixture
def store_run(tmp_path):
    ckpt = tmp_path / "policy.pt"
    ckpt.write_text("weights")
    rec = SqliteRecorder(tmp_path / "r.db")
    run_id = record_run(rec, "ours", 0, checkpoint=ckpt)
    return rec.store, rec.store.get_run(run_id)


def test_rows_hold_compare_designs_of_the_common_blocks(store_run):
    store, run = store_run
    backend = ScenarioBackend()
    built = []

    def factory(robot, simulator, objectives, *, checkpoint, agents_per_design, **kwargs):
        assert checkpoint.endswith("policy.pt") and agents_per_design == 8
        built.append(checkpoint)
        return backend

    assert yardstick_runs(store, [run], blocks=3, agents=8, steps=5, factory=factory) == {}
    assert backend.seeds == [scenario_seed(COMMON_SEED, b) for b in range(3)]
    best, nominal = yardstick_rows(store, run["id"])
    assert (best.idx, nominal.idx, best.kind) == (0, 1, "common") and nominal.design == [1.0, 1.0]
    assert best.design == run["summary"]["best_design"]
    # the same figures computed directly from the same per-scenario costs
    torque = get_registry().create("objective", "torque")
    fits = [
        ScenarioBackend().real_fitness(
            np.zeros((2, 2)), [torque], agents=8, steps=5, seed=scenario_seed(COMMON_SEED, b)
        )
        for b in range(3)
    ]
    per = np.concatenate([f.per_scenario for f in fits], axis=1)
    falls = np.concatenate([f.scenario_falls for f in fits], axis=1)
    want = compare_designs(CostRule.from_config(run["config"]), [torque], per, falls, 0, 1)
    got = yardstick_improvement(store, run["id"], "torque")
    assert got["improvement"] == pytest.approx(want["objectives"]["torque"]["improvement"])
    assert got["improvement_plain_se"] == pytest.approx(
        want["objectives"]["torque"]["improvement_plain_se"]
    )
    assert got["fall_rate"] == pytest.approx(falls[0].mean()) and got["nominal_fall_rate"] == 0.0
    assert got["fall_rate_difference"] == pytest.approx(falls[0].mean())
    # falls cost the cap: the capped improvement is below the unfallen 20 %, the plain
    # mean's further below
    assert got["improvement_plain"] < got["improvement"] < 0.2
    assert best.interactions == 3 * 8 * 5 and nominal.interactions == 3 * 8 * 5
    # stored once: a second call evaluates nothing
    assert yardstick_runs(store, [run], blocks=3, agents=8, steps=5, factory=factory) == {}
    assert len(built) == 1 and len(yardstick_rows(store, run["id"])) == 2


def test_a_run_without_policy_says_why(tmp_path):
    rec = SqliteRecorder(tmp_path / "r.db")
    run_id = record_run(rec, "ours", 0)  # no checkpoint recorded
    notes = yardstick_runs(
        rec.store, [rec.store.get_run(run_id)], factory=lambda *a, **k: pytest.fail("no backend")
    )
    assert notes == {run_id: "n/a: the run recorded no policy checkpoint"}
    assert yardstick_improvement(rec.store, run_id, "torque") is None


def test_a_block_is_the_size_of_the_runs_real_evaluation():
    from coadapt_core.experiments.yardstick import block_size

    assert block_size(
        {"config": {"eval_agents": 32, "eval_steps": 250, "agents_per_design": 16}}
    ) == (32, 250)
    assert block_size({"config": {"eval_agents": 0, "eval_steps": 20, "agents_per_design": 2}}) == (
        2,
        20,
    )


def test_a_run_without_a_shared_policy_evaluates_each_design_with_its_own(tmp_path):
    """A BO run: the best design with the best design's saved policy, the nominal design with
    the nominal's, looked up by name in the run folder; the same for the sim-to-sim check."""
    from coadapt_core.coadapt.specialized import OWN_POLICY_FILES
    from coadapt_core.experiments.transfer import transfer_runs

    rec = SqliteRecorder(tmp_path / "r.db")
    run_id = record_run(
        rec, "bo-specialized", 0, checkpoint=tmp_path / "policy-best.pt", optimizer="bo"
    )
    run = rec.store.get_run(run_id)
    (tmp_path / run["config"]["run_id"] / OWN_POLICY_FILES["nominal"]).write_text("weights")
    asked = []

    def factory(robot, simulator, objectives, *, checkpoint, **kwargs):
        role = checkpoint.rsplit("policy-", 1)[1].removesuffix(".pt")
        inner = ScenarioBackend()

        class Own:
            def real_fitness(self, designs, objectives, **kw):
                asked.append((simulator.name, role, np.asarray(designs).tolist()))
                fit = inner.real_fitness(designs, objectives, **kw)
                fit.per_scenario = fit.per_scenario * (0.8 if role == "best" else 1.0)
                fit.scenario_falls[:] = False
                return fit

        return Own()

    assert yardstick_runs(rec.store, [run], blocks=2, agents=8, steps=5, factory=factory) == {}
    best = run["summary"]["best_design"]
    assert asked == [("mujoco", "best", [best])] * 2 + [("mujoco", "nominal", [[1.0, 1.0]])] * 2
    got = yardstick_improvement(rec.store, run_id, "torque")
    assert got["improvement"] == pytest.approx(0.2)  # the best policy's 0.8 on the same scenarios
    asked.clear()
    assert transfer_runs(rec.store, [run], simulator="pybullet", factory=factory) == {}
    assert asked == [("pybullet", "best", [best]), ("pybullet", "nominal", [[1.0, 1.0]])]


def test_an_old_bo_run_whose_starting_policy_changed_says_why(tmp_path):
    rec = SqliteRecorder(tmp_path / "r.db")
    run_id = record_run(rec, "bo-specialized", 0, checkpoint=tmp_path / "other.pt", optimizer="bo")
    run = rec.store.get_run(run_id)
    run["config"].update(
        specialized_init="universal",
        checkpoint="",
        policy={"source": "shipped", "sha256": "0" * 64},
    )
    notes = yardstick_runs(rec.store, [run], factory=lambda *a, **k: pytest.fail("no backend"))
    assert notes == {
        run_id: "n/a: the starting policy flat.pt is not the one the run started from "
        "(SHA-256 differs); its policies cannot be trained again"
    }
