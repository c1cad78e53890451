"""`coadapt robot ...`: inspect, export, validate and render a robot's designs.

Every command takes a registered robot name and `--design` (comma-separated values in the
order of the robot's continuous or mixed design space; the nominal design when left out).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

from coadapt_core.cli import robot_new
from coadapt_core.cli.common import fail, resolve
from coadapt_core.cli.common_options import CommonOptions
from coadapt_core.cli.options import filled, options_of
from coadapt_core.cli.options import register as register_command
from coadapt_core.errors import DesignError, UserError
from coadapt_core.io import jsonable
from coadapt_core.robot import joint_table
from coadapt_core.settings import Int, setting, settings, shared

if TYPE_CHECKING:  # numpy is imported where it is used: listing the plugins loads none
    import numpy as np

app = typer.Typer(help="Inspect, export, validate and render robot designs.", no_args_is_help=True)

DESIGN_HELP = (
    "Design values, comma-separated in the order of the robot's design space (e.g. 1.2,0.8 or "
    "1.2,0.8,2,3 for kuafu). Default: the nominal design."
)


@settings
class RobotShow:
    """`coadapt robot show`'s settings; `robot` and `design` are shared by the other `robot`
    commands."""

    robot: str | None = setting(
        None,
        "Registered robot name (see `coadapt plugins`; default: the installed robot of "
        "highest default_rank, the only one when one is installed).",
        argument="[ROBOT]",
    )
    design: str | None = setting(None, DESIGN_HELP)
    as_json: Any = shared(CommonOptions)
    no_validate: bool = setting(False, "Skip the validation checks.", names=("--no-validate",))


@settings
class RobotExport:
    """`coadapt robot export`'s settings."""

    robot: Any = shared(RobotShow)
    design: Any = shared(RobotShow)
    format: str = setting("mjcf", "Model format: mjcf or urdf.")
    output: Path | None = setting(
        None, "File to write (default: standard output).", names=("-o", "--output")
    )


@settings
class RobotValidate:
    """`coadapt robot validate`'s settings."""

    robot: Any = shared(RobotShow)
    design: Any = shared(RobotShow)
    as_json: Any = shared(CommonOptions)


@settings
class RobotRender:
    """`coadapt robot render`'s settings."""

    robot: Any = shared(RobotShow)
    design: Any = shared(RobotShow)
    output: Path = setting(Path("design.png"), "PNG file to write.", names=("-o", "--output"))
    width: Int = setting(640, "Image width in pixels.")
    height: Int = setting(800, "Image height in pixels.")


#: exit code of `validate` for a design that fails a check
EXIT_INFEASIBLE = 1


def load_robot(name: str | None) -> Any:
    """An instance of the registered robot `name`, or of the default robot when None (one-line
    error listing the robots)."""
    from coadapt_core.cli.common import plugin_name

    return resolve("robot", plugin_name("robot", name))()


def parse_design(robot: Any, text: str | None) -> np.ndarray:
    """`text` as a design of the robot's continuous or mixed space (picked by arity), or the
    nominal design when `text` is None. Raises `DesignError` (one line) otherwise."""
    from coadapt_core.design_space import parse_numbers

    if text is None:
        return robot.nominal_design()
    plain, mixed = robot.design_space(False), robot.design_space(True)
    spaces = [plain] if plain.dim == mixed.dim else [plain, mixed]
    expected = " or ".join(f"{s.dim} values ({', '.join(s.names)})" for s in spaces)
    values = parse_numbers(
        text, what=f"--design '{text}' must be comma-separated numbers: {expected}"
    )
    for space in spaces:
        if len(values) == space.dim:
            return space.validate(values)
    raise DesignError(
        f"--design '{text}' has {len(values)} values; {robot.name} takes {expected}", field="design"
    )


def describe(robot: Any, design: np.ndarray, validate: bool = True) -> dict:
    """Everything `show` prints, as plain data."""
    model = robot.build(design)
    space = robot.design_space_for(design)
    joints = joint_table(model)
    out = {
        "robot": robot.name,
        "design": dict(zip(space.names, (float(x) for x in design), strict=True)),
        "total_mass": float(model.total_mass),
        "standing_base_height": float(model.standing_base_height),
        "info": jsonable(model.info),
        "joints": joints,
    }
    if validate:
        out["validation"] = robot.validate(design).to_dict()
    return out


def _console() -> Any:
    """A rich console; when output is not a terminal (pipes, files, tests) wide enough that
    the tables do not wrap."""
    from rich.console import Console

    console = Console()
    return console if console.is_terminal else Console(width=120)


def _print_description(data: dict) -> None:
    from rich.table import Table

    console = _console()
    design = ", ".join(f"{k}={v:g}" for k, v in data["design"].items())
    summary = Table(title=f"{data['robot']}  ({design})", show_header=False)
    summary.add_column("quantity")
    summary.add_column("value", justify="right")
    summary.add_row("total mass", f"{data['total_mass']:.3f} kg")
    summary.add_row("standing base height", f"{data['standing_base_height']:.3f} m")
    units = data["info"].get("units") if isinstance(data["info"].get("units"), dict) else {}
    for key, value in data["info"].items():
        unit = f" {units[key]}" if key in units and units[key] != "type" else ""
        if isinstance(value, int) and not isinstance(value, bool):
            summary.add_row(key.replace("_", " "), f"{value:d}{unit}")  # a motor type is an integer
        elif isinstance(value, float):
            summary.add_row(key.replace("_", " "), f"{value:.4g}{unit}")
        elif (
            key != "units"
            and isinstance(value, dict)
            and all(isinstance(v, int | float) for v in value.values())
        ):
            text = ", ".join(f"{k} {v:.3g}" for k, v in value.items())
            summary.add_row(key.replace("_", " ") + (f" ({unit.strip()})" if unit else ""), text)
        elif isinstance(value, str):
            summary.add_row(key.replace("_", " "), value)  # a spec robot's file, a note
        elif isinstance(value, dict) and all(isinstance(v, str) for v in value.values()):
            for name, text in value.items():  # a spec robot's mass rule per parameter
                summary.add_row(f"{key.replace('_', ' ')}: {name}", text)
    console.print(summary)
    joints = Table(title="actuated joints")
    motors = data["info"].get("motor_types")
    columns = [
        "joint",
        *(["motor"] if motors else []),
        "default",
        "range",
        "kp",
        "kd",
        "N m",
        "rad/s",
        "RPM",
    ]
    for column in columns:
        joints.add_column(column, justify="left" if column == "joint" else "right", no_wrap=True)
    for k, j in enumerate(data["joints"]):
        joints.add_row(
            j["name"],
            *([str(motors[k])] if motors else []),
            f"{j['default']:+.3f}",
            f"[{j['lower']:+.2f}, {j['upper']:+.2f}]",
            f"{j['kp']:.0f}",
            f"{j['kd']:.1f}",
            f"{j['torque_limit']:.1f}",
            f"{j['speed_limit']:.1f}",
            f"{j['speed_limit_rpm']:.0f}",
        )
    joints.caption = "range in rad; N m: peak torque; rad/s and RPM: no-load joint speed"
    console.print(joints)
    if "validation" in data:
        _print_findings(console, data["validation"])


def _print_findings(console: Any, report: dict) -> None:
    from rich.table import Table

    verdict = "feasible" if report["feasible"] else "INFEASIBLE"
    table = Table(title=f"validation: {verdict}")
    table.add_column("check")
    table.add_column("ok")
    table.add_column("finding")
    for f in report["findings"]:
        table.add_row(f["check"], "yes" if f["ok"] else "NO", f["message"])
    console.print(table)


_SHOW = options_of(RobotShow)


def show_command(**values: Any) -> None:
    """Lengths, masses, motor limits, PD gains and validation findings for one design."""
    o = filled(values, _SHOW)
    robot, design, as_json, no_validate = o["robot"], o["design"], o["as_json"], o["no_validate"]
    instance = load_robot(robot)
    values = parse_design(instance, design)
    data = describe(instance, values, validate=not no_validate)
    if as_json:
        print(json.dumps(data, indent=2))
    else:
        _print_description(data)


register_command(app, "show", show_command, _SHOW, path="robot show")
_EXPORT = options_of(RobotExport)


def export_command(**values: Any) -> None:
    """Write the design's model as MJCF (MuJoCo) or URDF (Pinocchio, PyBullet)."""
    o = filled(values, _EXPORT)
    robot, design, fmt, output = o["robot"], o["design"], o["format"], o["output"]
    if fmt not in ("mjcf", "urdf"):
        fail(f"--format '{fmt}' is not supported; use mjcf or urdf")
    instance = load_robot(robot)
    model = instance.build(parse_design(instance, design))
    text = model.text("mjcf") if fmt == "mjcf" else model.text("urdf")
    # the files the description names (a URDF's meshes): formats "<fmt>:<file name>"
    files = model.files(fmt)
    if output is None:
        if files:
            fail(f"the {fmt} names {len(files)} mesh files: give -o FILE to write them beside it")
        sys.stdout.write(text)
        return
    try:
        output.write_text(text)
        for name, content in files.items():
            (output.parent / Path(name).name).write_text(content)
    except OSError as exc:
        fail(f"cannot write -o {output}: {exc.strerror or exc}")
    also = f" and {len(files)} mesh files beside it" if files else ""
    print(
        f"wrote {fmt} of {instance.name} ({','.join(f'{x:g}' for x in model.design)}) to "
        f"{output}{also}",
        file=sys.stderr,
    )


register_command(app, "export", export_command, _EXPORT, path="robot export")
_VALIDATE = options_of(RobotValidate)


def validate_command(**values: Any) -> None:
    """Check a design: kinematics, mass, statics, MuJoCo/Pinocchio agreement (exit 1 if
    infeasible)."""
    o = filled(values, _VALIDATE)
    robot, design, as_json = o["robot"], o["design"], o["as_json"]
    instance = load_robot(robot)
    report = instance.validate(parse_design(instance, design))
    if as_json:
        print(json.dumps(report.to_dict(), indent=2))
    else:
        _print_findings(_console(), report.to_dict())
    if not report.feasible:
        for reason in report.reasons:
            print(f"infeasible: {reason}", file=sys.stderr)
        raise typer.Exit(EXIT_INFEASIBLE)


register_command(app, "validate", validate_command, _VALIDATE, path="robot validate")
# -- render ----------------------------------------------------------------------------------
_RENDER = options_of(RobotRender)


def render_command(**values: Any) -> None:
    """Offscreen MuJoCo picture of the design at its default pose, on a floor (PNG)."""
    o = filled(values, _RENDER)
    robot, design, output, width, height = (
        o["robot"],
        o["design"],
        o["output"],
        o["width"],
        o["height"],
    )
    # MUJOCO_GL is used when set; else EGL, then OSMesa
    if not (16 <= width <= 4096 and 16 <= height <= 4096):
        fail(f"--width and --height must lie in [16, 4096], got {width} x {height}")
    if not output.parent.is_dir():
        fail(f"cannot write -o {output}: folder {output.parent} does not exist")
    existed = output.exists()
    try:  # a read-only folder is said as such, not blamed on the GL backend after rendering
        with open(output, "ab"):
            pass
    except OSError as exc:
        fail(f"cannot write -o {output} ({exc.strerror}); give a writable path")
    if not existed:
        output.unlink()
    from coadapt_core.viz.video import model_format, offscreen, renderer_for

    instance = load_robot(robot)
    model = instance.build(parse_design(instance, design))
    try:
        renderer = renderer_for()
    except UserError as exc:  # no simulator can draw here (or its library refused this GL setting)
        fail(
            f"offscreen rendering failed ({exc}); install an EGL or OSMesa GL library, e.g. "
            "apt-get install -y libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1 (EGL) or libosmesa6 "
            "(OSMesa)",
            code=1,
        )
    payload = {
        "model": model.text(model_format(renderer)),
        "qpos_joints": [float(x) for x in model.default_joint_pos],
        "base_height": float(model.standing_base_height),
        "output": str(output),
        "width": width,
        "height": height,
    }
    backend, errors = offscreen("render_pose_png", payload, timeout=300, renderer=renderer)
    if backend is not None:
        print(f"wrote {output} ({width} x {height}, {backend})", file=sys.stderr)
        return
    fail(
        "offscreen rendering failed (" + "; ".join(errors) + "); install an EGL or OSMesa GL "
        "library, e.g. apt-get install -y libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1 (EGL) "
        "or libosmesa6 (OSMesa)",
        code=1,
    )


register_command(app, "render", render_command, _RENDER, path="robot render")
robot_new.register_new(app)


def register(parent: typer.Typer) -> None:
    """`coadapt robot` and its commands, on `parent` (`coadapt_core.cli.COMMANDS`)."""
    parent.add_typer(app, name="robot")
