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

from coadapt_core.io import jsonable
from coadapt_core.robot import joint_table


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
        if isinstance(value, dict):
            text = ", ".join(f"{k} {_num(v)}" for k, v in value.items())
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
        f"{ev['scenarios']} paired scenarios x {ev['steps'] if ev.get('steps') else '?'} steps per design."
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
        lines.append(
            f"| {name} | {_pm(row['design'], row.get('design_se'))} | "
            f"{_pm(row['nominal'], row.get('nominal_se'))} | {gain_text} |"
        )
    lines.append(
        f"| fall rate | {_num(ev.get('design_fall_rate'), 3)} | {_num(ev.get('nominal_fall_rate'), 3)} | |"
    )
    lines.append("")
    return lines


def render_markdown(sheet: dict[str, Any]) -> str:
    """`design.md`: the design sheet on one page."""
    d = sheet
    lines = [f"# {d['robot']} design {d['design_text']}", ""]
    prov = d["provenance"]
    lines += [
        f"From run `{prov['run_id']}` ({prov['method']}, {prov['optimizer']}, objective "
        f"{', '.join(prov['objectives'])}, terrain {d['terrain']}, seed {prov['seed']}); "
        f"{'the run' + chr(39) + 's best design' if d['is_run_best'] else 'a design chosen with --design'}. "
        "Units: SI (m, kg, s, rad, N m).",
        "",
    ]
    lines += [
        "## Design parameters",
        "",
        "| parameter | value | unit | allowed |",
        "|---|---|---|---|",
    ]
    for p in d["parameters"]:
        allowed = (
            "one of " + ", ".join(_num(c) for c in p["choices"])
            if p.get("choices")
            else f"[{_num(p['bounds'][0])}, {_num(p['bounds'][1])}]"
        )
        lines.append(f"| {p['name']} | {_num(p['value'])} | {p['unit']} | {allowed} |")
    body = d["body"]
    lines += [
        "",
        "## Body",
        "",
        f"Total mass {_num(body['total_mass'])} kg; overall height {_num(body['height'], 3)} m "
        f"(bounding boxes of the collision and visual geometry at the standing pose); standing base height "
        f"{_num(body['standing_base_height'], 3)} m.",
        "",
    ]
    info_rows = _info_rows(d["robot_info"])
    if info_rows:
        lines += ["| robot fact | value | unit |", "|---|---|---|", *info_rows, ""]
    lines += [
        "Links (from the MJCF; offset: distance of the link's frame from its parent's, for a serial leg the "
        "segment length above it; inertia: principal moments about the link's centre of mass):",
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
    lines += [
        "",
        "## Motors and joints (policy order)",
        "",
        "| joint | default rad | range rad | kp N m/rad | kd N m s/rad | peak torque N m | no-load speed rad/s (RPM) |",
        "|---|---|---|---|---|---|---|",
    ]
    for j in d["joints"]:
        lines.append(
            f"| {j['name']} | {j['default']:+.3f} | [{j['lower']:+.2f}, {j['upper']:+.2f}] | {_num(j['kp'])} | "
            f"{_num(j['kd'])} | {_num(j['torque_limit'])} | {_num(j['speed_limit'])} ({j['speed_limit_rpm']:.0f}) |"
        )
    val = d["validation"]
    lines += [
        "",
        f"## Validation: {'feasible' if val['feasible'] else 'INFEASIBLE'}",
        "",
        "| check | ok | finding |",
        "|---|---|---|",
    ]
    for f in val["findings"]:
        lines.append(f"| {f['check']} | {'yes' if f['ok'] else 'NO'} | {f['message']} |")
    lines += ["", "## Measured against the nominal design", ""]
    nominal_text = ", ".join(_num(x) for x in d["nominal_design"])
    lines.append(
        f"Nominal design ({nominal_text}). Costs are means per policy step (lower is better) with standard "
        "errors over paired scenarios: each scenario (command, randomization draw, spawn, gait phase, "
        "observation noise) is the same for both designs, so the improvement's error is paired."
    )
    judges = d.get("policies")
    if judges:
        lines.append(
            f"Policies: {judges['note']} (this design: `{judges['design']}`; nominal: `{judges['nominal']}`)."
        )
    lines.append("")
    for ev in d["evaluations"]:
        lines += _evaluation_lines(ev)
    check = d.get("controller_check")
    if check:
        lines += ["## The ONNX controller on the MJCF (check.py)", ""]
        if check.get("error"):
            lines.append(f"Not run: {check['error']}")
        else:
            lines.append(
                f"{check['seconds']:g} s at vx {check['command'][0]:g} m/s on {check['terrain']} ground, "
                f"nominal physics: survival {check['survival']:.2f}, mean forward speed {check['vx_mean']:.3f} m/s, "
                f"distance {check['distance_x']:.2f} m, lateral drift {check['lateral_drift']:+.2f} m."
            )
        lines.append("")
    onnx = d["onnx"]
    lines += [
        "## Controller",
        "",
        f"`policy.onnx`: ONNX max |action difference| from the torch policy {onnx['max_abs_action_difference']:.2e} "
        f"on {onnx['observations']} recorded observations (tolerance {onnx['tolerance']:g}). Observation, action "
        "and PD conventions: `policy.json`.",
        "",
        "## Provenance",
        "",
    ]
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
    return "\n".join(lines) + "\n"


__all__ = ["design_parameters", "joint_table", "jsonable", "render_markdown"]
