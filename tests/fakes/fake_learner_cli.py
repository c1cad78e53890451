"""`coadapt` with the analytic fake as its learner, for tests that drive the real command
line in a process of its own (Ctrl-C, piped progress): `python -m tests.fakes.fake_learner_cli
run ...`. Not a plugin and not shipped.

Environment: FAKE_DELAY, seconds each training phase and real round sleeps (default 0);
FAKE_VIDEO_SECONDS, the length of the fake rollouts the video draws (default 1). Each phase
announces itself on stderr ("fake: training", "fake: real round", "fake: drawing") so a
test knows where the run is when it sends a signal. The video is drawn for real (offscreen
MuJoCo, the robot's own model) from fake rollouts: a robot gliding forward in its default
pose.
"""

from __future__ import annotations

import os
import sys
import time
from typing import Any

import coadapt_core.coadapt.setup as loop_setup
import coadapt_core.viz.video as video
from tests.fakes.analytic import AnalyticBackend

DELAY = float(os.environ.get("FAKE_DELAY", "0"))
VIDEO_SECONDS = float(os.environ.get("FAKE_VIDEO_SECONDS", "1"))


def say(text: str) -> None:
    print(f"fake: {text}", file=sys.stderr, flush=True)


class SlowBackend(AnalyticBackend):
    def train(self, designs: Any, steps: int, *, seed: int = 0) -> Any:
        say("training")
        time.sleep(DELAY)
        return super().train(designs, steps, seed=seed)

    def real_fitness(self, designs: Any, objectives: Any, **kwargs: Any) -> Any:
        say("real round")
        time.sleep(DELAY)
        return super().real_fitness(designs, objectives, **kwargs)


def fake_rollout(
    checkpoint: Any, robot: Any, sim_cls: Any, design: Any, *, seconds: float, **kwargs: Any
) -> dict:
    model = robot.build(robot.check_design(design) if hasattr(robot, "check_design") else design)
    steps = int(VIDEO_SECONDS / 0.02)
    frames = [
        {
            "pos": [0.01 * k, 0.0, 0.55],
            "quat": [1.0, 0.0, 0.0, 0.0],
            "q": [0.0] * len(model.joint_names),
        }
        for k in range(steps)
    ]
    return {"_trajectory": {"frames": frames, "dt": 0.02}, "vx_mean": 0.5}


_offscreen = video.offscreen


def announced_offscreen(function: str, kwargs: dict, **rest: Any) -> Any:
    say("drawing")
    return _offscreen(function, kwargs, **rest)


def main() -> int:
    import coadapt_core.experiments.evaluate as evaluate

    loop_setup.universal_policy_factory = lambda *a, **k: lambda seed: SlowBackend(seed)
    evaluate.evaluate_checkpoint = fake_rollout
    video.offscreen = announced_offscreen
    from coadapt_core.cli import main as cli_main

    return cli_main(sys.argv[1:])


if __name__ == "__main__":
    sys.exit(main())
