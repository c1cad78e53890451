"""The offscreen scene of the run's video: a shadow map sized to the frame, not MuJoCo's 4096
default (0.22 s a 320 x 320 frame in software rendering, against 0.08-0.13 s)."""

from __future__ import annotations

import pytest

mujoco = pytest.importorskip("mujoco")


def test_the_shadow_map_follows_the_frame():
    from coadapt_plugins.simulators.mujoco.render import SHADOW_SIZE, scene_model

    from coadapt_core.plugins import get_registry

    robot = get_registry().get("robot", "kuafu")()
    mjcf = robot.build(robot.nominal_design()).text("mjcf")
    assert scene_model(mjcf, 320, 320).vis.quality.shadowsize == SHADOW_SIZE == 1024
    assert scene_model(mjcf, 480, 1600).vis.quality.shadowsize == 3200  # twice the larger side
    assert scene_model(mjcf, 320, 320, shadow_size=4096).vis.quality.shadowsize == 4096
