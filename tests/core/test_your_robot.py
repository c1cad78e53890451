"""docs/your-robot.md followed on a robot that is not in the repository: a six-legged walker
(18 joints, geometry-derived masses, no keyframe of ours to copy) brought as an MJCF file,
to `coadapt run --robot hexa --preset smoke` with no Python written. Every command is the
one the guide gives, run as a user runs it (a fresh `coadapt` process)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
GUIDE = ROOT / "docs" / "your-robot.md"

#: the smoke run made small, as the cluster tests make it (a few seconds on one core)
TINY = [
    *("--population", "3", "--agents-per-design", "2", "--eval-steps", "10"),
    *("--train-steps", "64", "--retrain-steps", "32", "--outer-iterations", "1"),
    *("--optimizer-iterations", "2", "--no-video"),
]


def hexapod_mjcf() -> str:
    """A hexapod: a 0.4 m body, six legs out to the sides, each a coxa (yaw), femur and tibia
    (both about x, mirrored on the right so a positive angle lifts either side), a sphere
    foot; masses from the geoms' density."""
    legs = []
    for row, x in (("f", 0.15), ("m", 0.0), ("r", -0.15)):
        for side, y in (("l", 1.0), ("r", -1.0)):
            n = f"{row}{side}"
            legs.append(
                f"""
      <body name="{n}_coxa" pos="{x} {0.1 * y} 0">
        <joint name="{n}_yaw" axis="0 0 1" range="-0.6 0.6"/>
        <geom type="sphere" size="0.02"/>
        <body name="{n}_femur" pos="0 {0.04 * y} 0">
          <joint name="{n}_lift" axis="{y} 0 0" range="-1 1"/>
          <geom type="capsule" fromto="0 0 0 0 {0.1 * y} 0" size="0.012"/>
          <body name="{n}_tibia" pos="0 {0.1 * y} 0">
            <joint name="{n}_knee" axis="{y} 0 0" range="-1 1"/>
            <geom type="capsule" fromto="0 0 0 0 0 -0.12" size="0.01"/>
            <body name="{n}_foot" pos="0 0 -0.12">
              <geom type="sphere" size="0.015"/>
            </body>
          </body>
        </body>
      </body>"""
            )
    motors = "".join(
        f'\n    <motor joint="{r}{s}_{j}" ctrlrange="-8 8"/>'
        for r in "fmr"
        for s in "lr"
        for j in ("yaw", "lift", "knee")
    )
    return f"""<mujoco model="hexa">
  <compiler angle="radian"/>
  <default><joint damping="0.05" armature="0.002"/><geom density="800"/></default>
  <worldbody>
    <geom type="plane" size="3 3 0.1"/>
    <body name="chassis" pos="0 0 0.3">
      <freejoint/>
      <geom type="box" size="0.2 0.08 0.03"/>{"".join(legs)}
    </body>
  </worldbody>
  <actuator>{motors}
  </actuator>
  <keyframe><key name="home" qpos="0 0 0.3 1 0 0 0 {" ".join(["0 0.25 -0.25"] * 6)}"/></keyframe>
</mujoco>
"""


def _coadapt(args: list[str], cwd: Path, robots: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, COADAPT_ROBOT_PATH=str(robots))
    env.pop("COADAPT_STORE", None)
    return subprocess.run(
        [sys.executable, "-m", "coadapt_core", *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )


def _guide_commands() -> list[str]:
    """The `coadapt ...` lines of the guide's walk-through block."""
    text = GUIDE.read_text()
    block = text.split("<!-- walk-through -->")[1].split("```bash")[1].split("```")[0]
    return [line.strip() for line in block.splitlines() if line.strip().startswith("coadapt ")]


@pytest.mark.slow
def test_the_guide_takes_a_new_robot_to_a_co_design_run(tmp_path):
    commands = _guide_commands()
    assert [c.split()[1:3] for c in commands] == [
        ["robot", "new"],
        ["robot", "validate"],
        ["run", "--robot"],
    ], commands
    (tmp_path / "hexa.xml").write_text(hexapod_mjcf())
    robots = tmp_path / "robots"
    # 1. the starting spec, written where the guide's COADAPT_ROBOT_PATH points
    new = commands[0].replace("NAME", "hexa").replace("MODEL.xml", "hexa.xml").split()[1:]
    done = _coadapt([*new, "--into", str(robots)], tmp_path, robots)
    assert done.returncode == 0, done.stderr
    assert "check (then edit it and run `coadapt robot validate hexa`)" in done.stdout
    spec = yaml.safe_load((robots / "hexa" / "robot.yaml").read_text())
    assert [leg["foot"] for leg in spec["legs"]] == [
        "fl_foot", "fr_foot", "ml_foot", "mr_foot", "rl_foot", "rr_foot",
    ]  # fmt: skip
    assert [leg["phase"] for leg in spec["legs"]] == [0.0, 0.5, 0.5, 0.0, 0.0, 0.5]  # tripod
    assert [p["name"] for p in spec["design"]] == ["femur_scale", "tibia_scale"]
    assert spec["standing_pose"] == {"keyframe": "home"}
    assert spec["limits"]["torque"]["fl_yaw"] == 8.0
    # 2. validation at the nominal design
    validate = commands[1].replace("NAME", "hexa").split()[1:]
    done = _coadapt([*validate, "--json"], tmp_path, robots)
    assert done.returncode == 0, done.stdout + done.stderr
    report = json.loads(done.stdout)
    assert report["feasible"] and {f["check"] for f in report["findings"]} >= {
        "pose.feet_on_ground",
        "statics.standing_torque",
        "consistency.pinocchio",
    }
    # 3. the co-design run on the smoke preset, from scratch (the robot ships no policy)
    run = commands[2].replace("NAME", "hexa").split()[1:]
    done = _coadapt(
        [*run, *TINY, "--store", f"sqlite:///{tmp_path / 'h.db'}", "--out", "runs"],
        tmp_path,
        robots,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    folder = Path(re.search(r"run folder: (\S+)", done.stdout).group(1))
    summary = json.loads((folder / "summary.json").read_text())
    config = yaml.safe_load((folder / "config.yaml").read_text())
    assert config["robot"] == "hexa" and summary["status"] == "finished"
    assert summary["nominal_design"] == [1.0, 1.0]
    assert len(summary["best_design"]) == 2 and all(0.7 <= v <= 1.3 for v in summary["best_design"])
    assert summary["best_cost"] > 0 and summary["real_evaluations"] > 0
