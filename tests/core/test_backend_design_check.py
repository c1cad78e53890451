"""Real fitness refuses a design outside the robot's space, on real MuJoCo: one `DesignError`
naming the variable, raised where designs become worlds (`Simulator._check_designs`) before
any environment changes, so the backend evaluates the next batch exactly as it would have."""

from __future__ import annotations

import numpy as np
import pytest

from coadapt_core.errors import DesignError
from coadapt_core.learning.backend import UniversalPolicyBackend
from coadapt_core.learning.config import TrainConfig
from coadapt_core.physics.randomization import RandomizationConfig
from coadapt_core.plugins import get_registry


def _backend():
    registry = get_registry()
    robot = registry.create("robot", "kuafu")
    objectives = [registry.create("objective", "torque")]
    backend = UniversalPolicyBackend(
        robot,
        registry.get("simulator", "mujoco"),
        objectives,
        terrain="flat",
        design_space=robot.design_space(),
        agents_per_design=2,
        seed=0,
        randomization=RandomizationConfig.off(),
        train_config=TrainConfig(
            agents_per_design=2, steps_per_env=8, epochs=1, minibatches=1, torch_threads=1
        ),
    )
    return robot, objectives, backend


def test_a_design_outside_the_space_is_refused_and_changes_nothing() -> None:
    robot, objectives, backend = _backend()
    space = robot.design_space()
    good = np.stack([robot.nominal_design(), space.lower])
    bad = np.stack([robot.nominal_design(), space.upper + np.array([0.0, 0.3])])
    try:
        with pytest.raises(DesignError) as caught:  # no evaluation environment yet
            backend.real_fitness(bad, objectives, agents=2, steps=5, seed=1)
        assert caught.value.field == space.names[1] and "outside its bounds" in str(caught.value)
        first = backend.real_fitness(good, objectives, agents=2, steps=5, seed=1)
        with pytest.raises(
            DesignError
        ) as caught:  # the built environment's designs swapped in place
            backend.real_fitness(bad, objectives, agents=2, steps=5, seed=1)
        assert caught.value.field == space.names[1]
        np.testing.assert_array_equal(
            backend.trainer.eval_env.sim.designs, np.repeat(good, 2, axis=0)
        )
        again = backend.real_fitness(good, objectives, agents=2, steps=5, seed=1)
        np.testing.assert_array_equal(again.per_scenario, first.per_scenario)
        assert np.isfinite(first.costs).all() and first.costs.shape == (2, 1)
    finally:
        backend.close()
