"""Scenario sets (`coadapt_core.scenarios` seeds them, `learning.evaluate` applies them) on
the fake simulator: what a scenario set gives every design of a batch, what the unpaired
protocol gives, and that the scenario seeds stay readable without torch (the results room
reads them through `coadapt_core.fitness`). The end-to-end pairing on real MuJoCo is
tests/core/test_paired_fitness.py."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import torch

from coadapt_core.errors import UserError
from coadapt_core.learning.evaluate import PairedStreams, apply_scenarios, prepare
from coadapt_core.scenarios.seeds import scenario_seed
from coadapt_core.task.config import TaskConfig
from coadapt_core.task.env import LocomotionEnv

DESIGNS, AGENTS = 3, 4


@pytest.fixture
def env(fake_robot, fake_sim_factory):
    designs = np.repeat(np.array([[0.7, 1.2], [1.0, 1.0], [1.3, 0.8]]), AGENTS, axis=0)
    out = LocomotionEnv(
        fake_sim_factory(designs=designs, randomize=True, seed=2), fake_robot, TaskConfig(), seed=2
    )
    yield out
    out.sim.close()


def groups(x: torch.Tensor) -> torch.Tensor:
    return x.reshape(DESIGNS, AGENTS, *x.shape[1:])


def test_the_seed_and_the_fitness_protocols_need_no_torch() -> None:
    assert scenario_seed(5, 1) == scenario_seed(5, 1) != scenario_seed(5, 2)
    probe = (
        "import json, sys, coadapt_core.fitness, coadapt_core.scenarios.seeds; "
        "print(json.dumps(['torch' in sys.modules, 'coadapt_core.physics' in sys.modules]))"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True
    ).stdout
    assert json.loads(out.strip().splitlines()[-1]) == [False, False]


def test_agent_i_of_every_design_gets_scenario_i(env) -> None:
    commands = apply_scenarios(env, AGENTS, DESIGNS, seed=11)
    assert commands.shape == (AGENTS, 3)
    obs, _, _ = env.reset()
    cmd, phase = groups(env.command), groups(env.phase)
    params = env.sim.env_params
    for k in range(1, DESIGNS):
        assert torch.equal(cmd[k], cmd[0]) and torch.equal(phase[k], phase[0])
        for field in ("friction", "motor_strength", "delay"):
            values = groups(torch.as_tensor(getattr(params, field)))
            assert torch.equal(values[k], values[0]), field
    assert (
        torch.equal(cmd[0], commands) and len(torch.unique(cmd[0], dim=0)) > 1
    )  # stratified over the box
    assert len(torch.unique(phase[0])) == AGENTS
    # the same observation noise and action noise for agent i of every design
    noisy = obs - env._observe(env.state)[1][:, : obs.shape[1]]
    assert torch.equal(groups(noisy)[1], groups(noisy)[0]) and noisy.abs().sum() > 0
    gen = torch.Generator()
    gen.manual_seed(3)
    draw = groups(env.paired_draw((env.num_envs, env.num_actions), gen))
    assert torch.equal(draw[2], draw[0]) and not torch.equal(draw[0, 0], draw[0, 1])
    # the scenario set is a function of its seed alone: applying it again draws it again
    first = (env.command.clone(), env.phase.clone())
    apply_scenarios(env, AGENTS, DESIGNS, seed=11)
    env.reset()
    assert torch.equal(env.command, first[0]) and torch.equal(env.phase, first[1])
    apply_scenarios(env, AGENTS, DESIGNS, seed=12)
    env.reset()
    assert not torch.equal(env.phase, first[1])


def test_unpaired_draws_per_environment_and_bad_groups_are_refused(env) -> None:
    prepare(env, AGENTS, DESIGNS, seed=11, paired=False)
    assert env.scenarios is None
    env.reset()
    phase = groups(env.phase)
    assert not torch.equal(phase[1], phase[0])  # every environment its own gait phase
    gen = torch.Generator()
    gen.manual_seed(3)
    draw = groups(env.paired_draw((env.num_envs, env.num_actions), gen))
    assert not torch.equal(draw[1], draw[0])
    with pytest.raises(UserError, match="do not split into groups of 5 agents"):
        apply_scenarios(env, 5, 2, seed=11)


def test_restart_streams_repeats_the_draws_of_an_unpaired_reset(env) -> None:
    phases = []
    for _ in range(2):
        env.restart_streams(7)
        env.use_scenarios(None)
        env.reset()
        phases.append((env.phase.clone(), torch.as_tensor(env.sim.env_params.friction).clone()))
    assert torch.equal(phases[0][0], phases[1][0]) and torch.equal(phases[0][1], phases[1][1])


def test_paired_streams_are_drawn_from_their_seed() -> None:
    a, b = (
        PairedStreams.draw(4, 9, torch.device("cpu")),
        PairedStreams.draw(4, 9, torch.device("cpu")),
    )
    assert (
        torch.equal(a.phase, b.phase)
        and a.phase.shape == (4,)
        and ((a.phase >= 0) & (a.phase < 1)).all()
    )
