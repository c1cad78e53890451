"""`coadapt_core.learning.factory`: the one construction site of the learner's backend."""

from __future__ import annotations

import pytest

from coadapt_core.errors import BackendUnavailable
from coadapt_core.fitness import CoadaptationBackend
from coadapt_core.learning.config import TrainConfig
from coadapt_core.learning.factory import make_backend
from tests.core.test_learning_backend import ShankLength, SquaredTorque


def test_make_backend_builds_the_universal_policy_as_asked(fake_robot, fake_sim_cls):
    config = TrainConfig(num_designs=2, agents_per_design=8, hidden=(32, 32), torch_threads=1)
    backend = make_backend(
        fake_robot,
        fake_sim_cls,
        [SquaredTorque(), ShankLength()],
        terrain="flat",
        agents_per_design=3,
        seed=7,
        train_config=config,
    )
    assert isinstance(backend, CoadaptationBackend)
    trainer = backend.trainer
    assert trainer.config.agents_per_design == 3  # the argument wins over the train config's 8
    assert trainer.config.seed == 7
    assert trainer.design_space == fake_robot.design_space()  # the robot's space by default
    assert [o.name for o in backend.objectives] == ["sq_torque", "speed_sq"]
    backend.close()


def test_an_unknown_simulator_name_is_backend_unavailable_naming_it(fake_robot):
    with pytest.raises(BackendUnavailable, match="unknown simulator 'no-such-sim'"):
        make_backend(fake_robot, "no-such-sim", [SquaredTorque()])
