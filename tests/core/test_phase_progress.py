"""Progress inside a training phase (issue 43): the training runner tells the phase's count
after every PPO iteration (`coadapt_core.phase_progress`), the loop turns it into progress
events with an ETA from the phase's measured rate, and `coadapt run`'s line shows it."""

from __future__ import annotations

import time

import pytest

import coadapt_core.coadapt.setup as loop_setup
from coadapt_core import phase_progress
from coadapt_core.learning.runner import Runner
from tests.core.test_runner import trainer_for
from tests.fakes.analytic import AnalyticBackend


def test_the_runner_reports_every_iteration_of_its_phase(fake_robot, fake_sim_cls):
    trainer = trainer_for(fake_robot, fake_sim_cls)  # 64 interactions an iteration
    heard: list[tuple[int, int]] = []
    with phase_progress.listening(lambda done, total: heard.append((done, total))):
        Runner(trainer).learn(150)  # 3 iterations
    assert heard == [(64, 192), (128, 192), (192, 192)]
    Runner(trainer).learn(64)  # nobody listening: nothing heard, nothing fails
    assert len(heard) == 3


def test_the_phase_eta_is_the_measured_rate_since_the_first_report():
    now = [100.0]
    rate = phase_progress.PhaseRate(clock=lambda: now[0])
    assert rate.eta(64, 640) is None  # the first report: the start-up before it is no rate
    now[0] += 4.0
    assert rate.eta(192, 640) == pytest.approx(4.0 * (640 - 192) / 128)  # 14 s
    now[0] += 4.0
    assert rate.eta(320, 640) == pytest.approx(8.0 * (640 - 320) / 256)  # 10 s
    assert rate.eta(640, 640) == 0.0


class ReportingBackend(AnalyticBackend):
    """Trains in 5 slices of 0.3 s, reporting each, as the runner does per iteration."""

    def train(self, designs, steps, *, seed=0):
        for k in range(1, 6):
            time.sleep(0.3)
            phase_progress.report(k * steps // 5, steps)
        return super().train(designs, steps, seed=seed)


def test_a_run_shows_its_training_phase_moving_with_an_eta(tmp_path, capsys, monkeypatch):
    from coadapt_core.cli import main

    monkeypatch.setattr(
        loop_setup, "universal_policy_factory", lambda *a, **k: lambda seed: ReportingBackend(seed)
    )
    monkeypatch.setenv("COADAPT_PROGRESS_EVERY", "0.2")
    assert (
        main(
            [
                "run",
                "--preset",
                "smoke",
                "--outer-iterations",
                "1",
                "--optimizer-iterations",
                "1",
                "--train-steps",
                "1000",
                "--out",
                str(tmp_path),
                "--store",
                "none",
                "--no-video",
            ]
        )
        == 0
    )
    lines = [
        line
        for line in capsys.readouterr().err.splitlines()
        if "training " in line and "% of 1,000" in line
    ]
    shown = [int(line.split("training ")[1].split("%")[0]) for line in lines]
    assert shown and shown == sorted(shown) and shown[-1] >= 60, lines
    # from the second report on, the phase's ETA is a duration measured from its rate
    # (0.3 s a fifth)
    etas = [
        line.split("phase ETA ")[1].split()[0]
        for line in lines
        if "% of 1,000, phase ETA 0:" in line
    ]
    assert etas and all(e in ("0:00:00", "0:00:01") for e in etas), lines
    assert any(f"  {n:,} interactions" in line for line in lines for n in (400, 600, 800)), lines
