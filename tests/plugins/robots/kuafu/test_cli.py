"""`coadapt robot show | export | validate | render` on kuafu, and one-line errors for bad
designs (exit code 2)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from coadapt_plugins.robots.kuafu.robot import Kuafu

from coadapt_core.cli import main
from coadapt_core.robot import Finding, ValidationReport


def cli(capsys, *args: str) -> tuple[int, str, str]:
    code = main(["robot", *args])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_show_json_reports_lengths_motors_and_validation(capsys):
    code, out, _ = cli(capsys, "show", "kuafu", "--design", "1.2,0.8,2,3", "--json")
    assert code == 0
    data = json.loads(out)
    assert data["design"] == {
        "thigh_scale": 1.2,
        "shank_scale": 0.8,
        "hip_motor": 2.0,
        "knee_motor": 3.0,
    }
    assert data["info"]["thigh_length"] == pytest.approx(0.42)
    assert data["info"]["shank_length"] == pytest.approx(0.28)
    assert [j["name"] for j in data["joints"]][:4] == [
        "left_hip_roll",
        "left_hip_pitch",
        "left_knee",
        "left_ankle",
    ]
    assert [j["torque_limit"] for j in data["joints"]][:4] == [120.3, 120.3, 135.1, 119.7]
    assert data["joints"][2]["speed_limit_rpm"] == pytest.approx(310.0)
    assert data["total_mass"] == pytest.approx(Kuafu().build(np.array([1.2, 0.8, 2, 3])).total_mass)
    assert data["validation"]["feasible"] is True
    assert len(data["validation"]["findings"]) == 13


def test_show_table_defaults_to_the_nominal_design(capsys):
    code, out, _ = cli(capsys, "show", "kuafu")
    assert code == 0
    assert "thigh_scale=1, shank_scale=1" in out
    assert "42.000 kg" in out
    assert "left_knee" in out and "validation: feasible" in out and "statics.single_support" in out


@pytest.mark.parametrize("fmt", ["urdf", "mjcf"])
def test_export_writes_a_loadable_model(capsys, tmp_path, fmt):
    target = tmp_path / f"kuafu.{fmt}"
    code, _, err = cli(
        capsys, "export", "kuafu", "--design", "0.7,1.3", "--format", fmt, "-o", str(target)
    )
    assert code == 0 and str(target) in err
    text = target.read_text()
    if fmt == "urdf":
        pmodel = pin.buildModelFromXML(text, pin.JointModelFreeFlyer())
        assert pmodel.nv == 14
        assert pin.computeTotalMass(pmodel) == pytest.approx(
            Kuafu().build(np.array([0.7, 1.3])).total_mass
        )
    else:
        mj = mujoco.MjModel.from_xml_string(text)
        assert (mj.nq, mj.nv, mj.nu) == (15, 14, 8)


def test_export_to_stdout(capsys):
    code, out, _ = cli(capsys, "export", "kuafu", "--format", "mjcf")
    assert code == 0 and out.startswith('<mujoco model="kuafu">')


def test_validate_exit_codes(capsys, monkeypatch):
    code, out, err = cli(capsys, "validate", "kuafu", "--design", "0.5,1.5")
    assert code == 0 and "feasible" in out and err == ""

    def infeasible(self, design):
        return ValidationReport(
            np.asarray(design),
            [
                Finding(
                    "statics.single_support",
                    False,
                    "largest gravity torque 150.0 N m at left_knee vs limit 119.7 N m",
                ),
                Finding("mass.total", True, "42.000 kg"),
            ],
        )

    monkeypatch.setattr(Kuafu, "validate", infeasible)
    code, out, err = cli(capsys, "validate", "kuafu", "--design", "1,1", "--json")
    assert code == 1
    assert json.loads(out)["feasible"] is False
    assert err.strip().splitlines() == [
        "infeasible: statics.single_support: largest gravity torque 150.0 N m at left_knee vs "
        "limit 119.7 N m"
    ]


@pytest.mark.parametrize(
    "design, words",
    [
        ("1.7,0.8", ["thigh_scale", "1.7", "[0.5, 1.5]"]),
        ("1.2,0.4", ["shank_scale", "0.4", "[0.5, 1.5]"]),
        ("1.2,0.8,4,1", ["hip_motor", "4", "{1, 2, 3}"]),
        ("1.2,0.8,1,2.5", ["knee_motor", "2.5", "{1, 2, 3}"]),
        ("1,2,3", ["3 values", "2 values (thigh_scale, shank_scale)", "4 values"]),
        ("a,b", ["comma-separated numbers", "thigh_scale"]),
    ],
)
def test_bad_designs_are_one_line_exit_2(capsys, design, words):
    for command in (
        ["show", "kuafu", "--design", design],
        ["validate", "kuafu", "--design", design],
        ["export", "kuafu", "--design", design],
    ):
        code, _, err = cli(capsys, *command)
        assert code == 2
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: ")
        for word in words:
            assert word in lines[0]


def test_unknown_robot_and_format(capsys):
    code, _, err = cli(capsys, "show", "nosuchbot")
    assert code == 2 and err.strip().startswith("error: unknown robot 'nosuchbot'; available: ")
    assert "kuafu" in err.strip().rsplit(": ", 1)[1].split(", ")
    code, _, err = cli(capsys, "export", "kuafu", "--format", "stl")
    assert code == 2 and "mjcf or urdf" in err


def test_bad_design_in_a_fresh_process_is_one_line_no_traceback():
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from coadapt_core.cli import main; sys.exit(main(sys.argv[1:]))",
            "robot",
            "validate",
            "kuafu",
            "--design",
            "1.2,0.8,7,1",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip() == "error: design variable 'hip_motor' = 7 is not one of {1, 2, 3}"


@pytest.mark.slow
def test_render_writes_a_picture(tmp_path):
    target = tmp_path / "design.png"
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from coadapt_core.cli import main; sys.exit(main(sys.argv[1:]))",
            "robot",
            "render",
            "kuafu",
            "--design",
            "1.2,0.8",
            "-o",
            str(target),
            "--width",
            "160",
            "--height",
            "200",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    if proc.returncode == 1 and "offscreen rendering failed" in proc.stderr:
        pytest.skip(f"no GL backend for offscreen rendering: {proc.stderr.strip()}")
    assert proc.returncode == 0, proc.stderr
    import matplotlib.image

    pixels = matplotlib.image.imread(target)
    assert pixels.shape[:2] == (200, 160)
    assert pixels[..., :3].std() > 0.05  # a picture, not a blank frame


@pytest.mark.slow
def test_render_without_a_gl_backend_is_one_line_exit_1(tmp_path):
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from coadapt_core.cli import main; sys.exit(main(sys.argv[1:]))",
            "robot",
            "render",
            "kuafu",
            "-o",
            str(tmp_path / "x.png"),
            "--width",
            "64",
            "--height",
            "64",
        ],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "MUJOCO_GL": "not-a-backend"},
    )
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert (
        len(lines) == 1
        and "offscreen rendering failed" in lines[0]
        and "apt-get install" in lines[0]
    )


def test_render_into_a_missing_folder_is_exit_2(capsys, tmp_path):
    code, _, err = cli(capsys, "render", "kuafu", "-o", str(tmp_path / "nope" / "x.png"))
    assert code == 2 and "does not exist" in err
