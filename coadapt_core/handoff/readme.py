"""The handoff folder's README: the files, how to load the model and run the controller in
a few lines (the simulator's own words), the observation layout, and how to check it."""

from __future__ import annotations

from typing import Any

from coadapt_core import __version__

CHECK_SECTION = """## Check it

    python check.py             # 10 s at 0.5 m/s on the model: survival, speed, ONNX vs torch
    python check.py --json --seconds 20 --vx 0.3

"""


def readme_text(
    spec: dict[str, Any], sheet_data: dict[str, Any], files: list[tuple[str, str]], usage: str = ""
) -> str:
    """The README; `usage` is the simulator's section on loading the model and running the
    controller (its model tools' `handoff_usage`), "" for none."""
    obs = spec["observation"]
    layout = "\n".join(
        f"| {s['start']}:{s['stop']} | {s['name']} | {s['units']} | {s['meaning']} |"
        for s in obs["slices"]
    )
    check = sheet_data.get("controller_check") or {}
    walked = (
        ""
        if not check or check.get("error")
        else "\nWhen this folder was written, `python check.py` printed: survival "
        f"{check['survival']:.2f}, mean forward speed {check['vx_mean']:.3f} m/s under a "
        f"{check['command'][0]:g} m/s command for {check['seconds']:g} s.\n"
    )
    has_check = any(name == "check.py" for name, _ in files)
    run_id = sheet_data["provenance"]["run_id"]
    rows = "\n".join(f"| `{name}` | {what} |" for name, what in files)
    check_section = CHECK_SECTION if has_check else ""
    return f"""# {spec["robot"]} {spec["design_text"]}: model, controller and design sheet

Written by `coadapt handoff` (coadapt {__version__}) from run `{run_id}`.

| file | what |
|---|---|
{rows}

{usage}{walked}
## The observation (`obs`, {obs["size"]} float32 values, SI units, no scaling)

| slice | name | units | meaning |
|---|---|---|---|
{layout}

The graph normalises the observation itself (the training normaliser's mean and std, clipped
at ±{obs["normalisation"]["clip"]:g}) and returns `actions` (raw, feed back into the history) and
`joint_targets` = default pose + {spec["action"]["scale"]:g} x actions (rad). Observation
noise used in training is listed per slice in `policy.json` (`training_noise`); add none on
the robot. Commands the policy was trained on: `policy.json` `commands.trained`.

{check_section}The design sheet is `design.md` (`design.json` holds the same as data).
"""
