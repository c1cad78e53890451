"""Exact resume on the real learner (issue 7): a `UniversalPolicyBackend` loaded from a
checkpoint trains and evaluates exactly as the one that saved it, and a real-MuJoCo smoke
co-adaptation run interrupted twice and resumed ends exactly as an uninterrupted one."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from coadapt_plugins.objectives.locomotion import TorqueObjective

from coadapt_core.coadapt.config_loading import make_config
from coadapt_core.coadapt.run import run_coadaptation
from coadapt_core.coadapt.setup import build_parts
from coadapt_core.learning.backend import UniversalPolicyBackend
from coadapt_core.learning.config import TrainConfig
from coadapt_core.plugins import get_registry
from coadapt_core.results.recorders import read_evaluations

pytestmark = pytest.mark.slow


def tiny_backend(seed: int = 11) -> UniversalPolicyBackend:
    registry = get_registry()
    robot = registry.create("robot", "kuafu")
    config = TrainConfig(
        agents_per_design=2,
        steps_per_env=8,
        hidden=(32, 32),
        epochs=2,
        minibatches=2,
        torch_threads=1,
    )
    return UniversalPolicyBackend(
        robot,
        registry.get("simulator", "mujoco"),
        [TorqueObjective()],
        terrain="random",
        design_space=robot.design_space(),
        agents_per_design=2,
        device="cpu",
        seed=seed,
        train_config=config,
    )


def weights(backend: UniversalPolicyBackend) -> dict[str, torch.Tensor]:
    state = backend.ppo.state_dict()
    return {
        f"{part}.{k}": v.clone()
        for part in ("actor", "critic", "pseudo_critic", "obs_norm", "critic_norm", "pseudo_norm")
        for k, v in state[part].items()
    }


def test_a_loaded_backend_evaluates_and_trains_exactly_as_the_one_that_saved(tmp_path) -> None:
    first = tiny_backend()
    # a history the loaded copy never sees: two trainings, evaluations of other designs
    first.train(np.array([[1.0, 1.0], [0.7, 1.3]]), 32, seed=1)
    first.real_fitness(
        np.array([[0.6, 0.9], [1.3, 1.3], [0.8, 0.7]]), first.objectives, agents=2, steps=10, seed=5
    )
    first.train(np.array([[1.2, 0.8], [0.9, 1.1]]), 32, seed=2)
    first.trainer.env.commands.limit = 0.85  # as if the curriculum had widened the box
    path = tmp_path / "backend.pt"
    first.save(str(path))
    second = tiny_backend()
    second.load(str(path))
    designs = np.array([[0.5, 0.5], [1.0, 1.0], [1.5, 1.2]])
    costs = [
        b.real_fitness(designs, b.objectives, agents=2, steps=15, seed=7).costs
        for b in (first, second)
    ]
    np.testing.assert_array_equal(costs[0], costs[1])
    assert (
        np.all(np.isfinite(costs[0])) and len(np.unique(costs[0])) == 3
    )  # three designs, three costs
    other_seed = first.real_fitness(designs, first.objectives, agents=2, steps=15, seed=8).costs
    assert not np.array_equal(other_seed, costs[0])  # the seed does reach the rollout
    results = [b.train(np.array([[0.8, 1.4], [1.1, 0.6]]), 32, seed=3) for b in (first, second)]
    assert results[0].mean_reward == results[1].mean_reward
    a, b = weights(first), weights(second)
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    assert first.ppo.learning_rate == second.ppo.learning_rate
    after = [
        b.real_fitness(designs, b.objectives, agents=2, steps=15, seed=7).costs
        for b in (first, second)
    ]
    np.testing.assert_array_equal(after[0], after[1])
    assert not np.array_equal(after[0], costs[0])  # the training changed the policy
    first.close()
    second.close()


SMOKE = dict(
    optimizer="pso",
    sim="mujoco",
    objective="torque",
    seed=0,
    eval_steps=12,
    train_steps=240,
    retrain_steps=120,
)


def interrupting(config, kind: str, call: int):
    """The real backend factory, with its `call`-th `kind` call ("train" / "real") in this
    process raising as a kill would, before doing any work."""
    real = build_parts(config).backend_factory
    counts = {"train": 0, "real": 0}

    def factory(seed: int):
        backend = real(seed)
        for key, attr in (("train", "train"), ("real", "real_fitness")):
            original = getattr(backend, attr)

            def wrapped(*args, _original=original, _key=key, **kwargs):
                if _key == kind and counts[_key] == call:
                    raise KeyboardInterrupt(f"injected before {kind} call {call}")
                counts[_key] += 1
                return _original(*args, **kwargs)

            setattr(backend, attr, wrapped)
        return backend

    return factory


def records(run_dir):
    return [
        (r["outer"], r["inner"], r["kind"], r["idx"], r["design"], r["costs"], r["interactions"])
        for r in read_evaluations(run_dir)
    ]


def test_smoke_run_interrupted_twice_and_resumed_equals_the_uninterrupted_run(tmp_path) -> None:
    config = make_config("smoke", overrides={**SMOKE, "out": str(tmp_path)})
    full = run_coadaptation(config, run_dir=tmp_path / "full").summary

    cut = tmp_path / "cut"
    # 1: between the two evaluation rounds of the first outer iteration (real calls: round 0, the
    # nominal design's reference evaluation of the capped cost rule, round 1)
    with pytest.raises(KeyboardInterrupt, match="injected"):
        run_coadaptation(config, run_dir=cut, backend_factory=interrupting(config, "real", 2))
    done_first = len(read_evaluations(cut))
    # 2: the resumed process is stopped again as it starts retraining (second outer iteration)
    with pytest.raises(KeyboardInterrupt, match="injected"):
        run_coadaptation(resume=cut, backend_factory=interrupting(config, "train", 0))
    done_second = len(read_evaluations(cut))
    resumed = run_coadaptation(resume=cut).summary

    assert 0 < done_first < done_second < len(records(tmp_path / "full"))  # both cuts fell mid-run
    assert resumed["best_design"] == full["best_design"]
    assert (
        resumed["best_costs"] == full["best_costs"]
    )  # bit-identical real costs of the final check
    assert resumed["nominal_costs"] == full["nominal_costs"]
    assert resumed["interactions"] == full["interactions"]
    assert [b["best_cost"] for b in resumed["batches"]] == [b["best_cost"] for b in full["batches"]]
    assert records(cut) == records(tmp_path / "full")  # every evaluated design, with its cost
