"""The design sheet of a handoff folder: what the design is (parameters with units, links
with their lengths, masses and inertias, motors, total mass and height, the robot's own
validation) and what it was measured to do (objective costs with standard errors and fall
rates against the nominal design on paired scenarios, per simulator), as `design.json` and
the one-page `design.md`.

Link facts come from the run's simulator's model tools (`coadapt_core.physics.model_tools`:
the design's model compiled, nothing simulated), so they hold for any robot plugin: each
body's offset from its parent (for a serial leg, the length of the segment above it), mass,
centre of mass and principal moments of inertia.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def design_parameters(space: Any, design: np.ndarray) -> list[dict[str, Any]]:
    """Each design variable: name, value, unit (as the design space declares it), bounds."""
    out = []
    for k, var in enumerate(space.variables):
        entry = {
            "name": var.name,
            "value": float(design[k]),
            "unit": getattr(var, "unit", "") or "",
        }
        bounds = (float(space.lower[k]), float(space.upper[k]))
        entry["bounds"] = list(bounds)
        choices = getattr(var, "choices", None)
        if choices is not None:
            entry["choices"] = [float(c) for c in choices]
        out.append(entry)
    return out


# -- design.md -----------------------------------------------------------------------------------
def _num(x: Any, digits: int = 4) -> str:
    if x is None:
        return "-"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return str(x)
    x = float(x)
    if not math.isfinite(x):
        return "-"
    return f"{x:.{digits}g}"


def _pm(value: Any, se: Any) -> str:
    return _num(value) if se is None else f"{_num(value)} ± {_num(se, 2)}"


def _info_rows(info: dict[str, Any]) -> list[str]:
    units = info.get("units") if isinstance(info.get("units"), dict) else {}
    rows = []
    for key, value in info.items():
        if key == "units":
            continue
        unit = units.get(key, "")
        unit = "" if unit == "type" else unit
        if isinstance(value, dict):  # numbers (segment masses) or lines (a spec's mass rules)
            text = ", ".join(
                f"{k} {_num(v) if isinstance(v, int | float) else v}" for k, v in value.items()
            )
        elif isinstance(value, list | tuple):
            text = ", ".join(_num(v) for v in value)
        else:
            text = _num(value) if isinstance(value, int | float) else str(value)
        rows.append(f"| {key.replace('_', ' ')} | {text} | {unit} |")
    return rows


def _evaluation_lines(ev: dict[str, Any]) -> list[str]:
    """One evaluation of the design sheet: costs with standard errors, improvements, falls."""
    lines = [f"### {ev['simulator']}: {ev['source']}", ""]
    if ev.get("error"):
        return [*lines, f"Not evaluated: {ev['error']}", ""]
    lines.append(
        f"{ev['scenarios']} paired scenarios x {ev['steps'] if ev.get('steps') else '?'} steps "
        "per design."
        if ev.get("scenarios")
        else ""
    )
    lines += ["", "| objective | this design | nominal | improvement |", "|---|---|---|---|"]
    for name, row in ev["objectives"].items():
        gain = row.get("improvement")
        gain_text = (
            "-"
            if gain is None
            else f"{100 * gain:+.1f} %"
            + ("" if row.get("improvement_se") is None else f" ± {100 * row['improvement_se']:.1f}")
        )
        if ev.get("refusal"):  # falls decide: no percentage (the protocol's line says why)
            gain_text = "no answer (below)"
        lines.append(
            f"| {name} | {_pm(row['design'], row.get('design_se'))} | "
            f"{_pm(row['nominal'], row.get('nominal_se'))} | {gain_text} |"
        )
    lines.append(
        f"| fall rate | {_num(ev.get('design_fall_rate'), 3)} | "
        f"{_num(ev.get('nominal_fall_rate'), 3)} | |"
    )
    lines.append("")
    if ev.get("sim_to_sim"):  # the sim-to-sim protocol's line, as `coadapt report` prints it
        lines += [f"Sim-to-sim protocol ({ev.get('cost_rule')} cost rule): {ev['sim_to_sim']}", ""]
    return lines


def render_markdown(sheet: dict[str, Any]) -> str:
    """`design.md`: the design sheet on one page."""
    d = sheet
    lines = [f"# {d['robot']} design {d['design_text']}", "", _origin(d), ""]
    lines += _parameter_lines(d["parameters"])
    lines += _body_lines(d["body"], d["robot_info"])
    lines += _joint_lines(d["joints"])
    lines += _validation_lines(d["validation"])
    lines += _measured_lines(d)
    check = d.get("controller_check")
    if check:
        lines += ["## The ONNX controller on the MJCF (check.py)", "", _check_text(check), ""]
    onnx = d["onnx"]
    lines += [
        "## Controller",
        "",
        "`policy.onnx`: ONNX max |action difference| from the torch policy "
        f"{onnx['max_abs_action_difference']:.2e} on {onnx['observations']} recorded "
        f"observations (tolerance {onnx['tolerance']:g}). Observation, action and PD "
        "conventions: `policy.json`.",
        "",
        "## Provenance",
        "",
    ]
    lines += _provenance_lines(d["provenance"])
    return "\n".join(lines) + "\n"


def _origin(d: dict[str, Any]) -> str:
    """Where the design comes from: the run, its method and objective, which design."""
    prov = d["provenance"]
    which = "the run's best design" if d["is_run_best"] else "a design chosen with --design"
    return (
        f"From run `{prov['run_id']}` ({prov['method']}, {prov['optimizer']}, objective "
        f"{', '.join(prov['objectives'])}, terrain {d['terrain']}, seed {prov['seed']}); "
        f"{which}. Units: SI (m, kg, s, rad, N m)."
    )


def _parameter_lines(parameters: list[dict[str, Any]]) -> list[str]:
    lines = [
        "## Design parameters",
        "",
        "| parameter | value | unit | allowed |",
        "|---|---|---|---|",
    ]
    for p in parameters:
        allowed = (
            "one of " + ", ".join(_num(c) for c in p["choices"])
            if p.get("choices")
            else f"[{_num(p['bounds'][0])}, {_num(p['bounds'][1])}]"
        )
        lines.append(f"| {p['name']} | {_num(p['value'])} | {p['unit']} | {allowed} |")
    return lines


def _body_lines(body: dict[str, Any], robot_info: dict[str, Any]) -> list[str]:
    """Total mass and height, the robot's own facts and each link of the MJCF."""
    lines = [
        "",
        "## Body",
        "",
        f"Total mass {_num(body['total_mass'])} kg; overall height {_num(body['height'], 3)} m "
        "(bounding boxes of the collision and visual geometry at the standing pose); standing "
        f"base height {_num(body['standing_base_height'], 3)} m.",
        "",
    ]
    info_rows = _info_rows(robot_info)
    if info_rows:
        lines += ["| robot fact | value | unit |", "|---|---|---|", *info_rows, ""]
    lines += [
        "Links (from the MJCF; offset: distance of the link's frame from its parent's, for a "
        "serial leg the segment length above it; inertia: principal moments about the link's "
        "centre of mass):",
        "",
        "| link | parent | joints | offset m | mass kg | principal inertia kg m² |",
        "|---|---|---|---|---|---|",
    ]
    for link in body["links"]:
        inertia = ", ".join(_num(v, 3) for v in link["principal_inertia"])
        lines.append(
            f"| {link['name']} | {link['parent']} | {', '.join(link['joints']) or '-'} | "
            f"{_num(link['offset_from_parent'], 3)} | {_num(link['mass'])} | {inertia} |"
        )
    return lines


def _joint_lines(joints: list[dict[str, Any]]) -> list[str]:
    lines = [
        "",
        "## Motors and joints (policy order)",
        "",
        "| joint | default rad | range rad | kp N m/rad | kd N m s/rad | peak torque N m | "
        "no-load speed rad/s (RPM) |",
        "|---|---|---|---|---|---|---|",
    ]
    for j in joints:
        lines.append(
            f"| {j['name']} | {j['default']:+.3f} | [{j['lower']:+.2f}, {j['upper']:+.2f}] | "
            f"{_num(j['kp'])} | {_num(j['kd'])} | {_num(j['torque_limit'])} | "
            f"{_num(j['speed_limit'])} ({j['speed_limit_rpm']:.0f}) |"
        )
    return lines


def _validation_lines(val: dict[str, Any]) -> list[str]:
    lines = [
        "",
        f"## Validation: {'feasible' if val['feasible'] else 'INFEASIBLE'}",
        "",
        "| check | ok | finding |",
        "|---|---|---|",
    ]
    for f in val["findings"]:
        lines.append(f"| {f['check']} | {'yes' if f['ok'] else 'NO'} | {f['message']} |")
    return lines


def _measured_lines(d: dict[str, Any]) -> list[str]:
    """The design against the nominal one: how to read the costs, which policies judged
    them, and each evaluation."""
    lines = ["", "## Measured against the nominal design", ""]
    nominal_text = ", ".join(_num(x) for x in d["nominal_design"])
    lines.append(
        f"Nominal design ({nominal_text}). Costs are means per policy step (lower is better) "
        "with standard errors over paired scenarios: each scenario (command, randomization "
        "draw, spawn, gait phase, observation noise) is the same for both designs, so the "
        "improvement's error is paired."
    )
    judges = d.get("policies")
    if judges:
        lines.append(
            f"Policies: {judges['note']} (this design: `{judges['design']}`; nominal: "
            f"`{judges['nominal']}`)."
        )
    lines.append("")
    for ev in d["evaluations"]:
        lines += _evaluation_lines(ev)
    return lines


def _check_text(check: dict[str, Any]) -> str:
    """What check.py measured walking the ONNX controller on the MJCF, or why it did not."""
    if check.get("error"):
        return f"Not run: {check['error']}"
    return (
        f"{check['seconds']:g} s at vx {check['command'][0]:g} m/s on {check['terrain']} "
        f"ground, nominal physics: survival {check['survival']:.2f}, mean forward speed "
        f"{check['vx_mean']:.3f} m/s, distance {check['distance_x']:.2f} m, lateral drift "
        f"{check['lateral_drift']:+.2f} m."
    )


def _provenance_lines(prov: dict[str, Any]) -> list[str]:
    lines = []
    for key, value in prov.items():
        text = (
            ", ".join(map(str, value))
            if isinstance(value, list)
            else ("-" if value is None else str(value))
        )
        lines.append(
            f"- {key.replace('_', ' ')}: `{text}`"
            if value is not None
            else f"- {key.replace('_', ' ')}: -"
        )
    return lines


__all__ = ["design_parameters", "render_markdown"]
