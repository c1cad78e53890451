"""Pictures and videos of robot designs through a simulator plugin's offscreen renderer: a
design's default pose as a PNG (`coadapt robot render`), a recorded rollout as a GIF or MP4
(`coadapt eval --video`), and a run's answer, the best design and the nominal one walking
side by side under the run's final policy (`coadapt run`; no GL backend there is a one-line
note, never a failed run).

A simulator that can draw declares `renderer` (`coadapt_core.physics.simulator.Simulator`):
a module defining `MODEL_FORMAT` (the robot model format it draws), `environments()` (the
settings to try in turn, e.g. GL backends) and the functions `render_pose_png` and
`render_panels`. A graphics library may pick its backend when first imported, so every
picture is drawn in a fresh interpreter (`offscreen`) that tries the environments in turn."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

VIDEO_NAME = "best_vs_nominal"


def renderer_for(simulator: str | None = None) -> str:
    """The renderer module (a dotted path) of `simulator` when its plugin declares one, else
    of the first installed simulator that does (the default one first); a one-line
    `UserError` when none does."""
    from coadapt_core.errors import UserError
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    names = registry.names("simulator")
    order = (
        ([simulator] if simulator else [])
        + ([registry.default("simulator")] if names else [])
        + names
    )
    for name in dict.fromkeys(order):
        if name in names and getattr(registry.get("simulator", name), "renderer", ""):
            return str(registry.get("simulator", name).renderer)
    broken = "".join(
        f"; {b.line()}" for b in registry.broken
    )  # e.g. a GL setting its library refuses
    raise UserError(
        "no installed simulator plugin declares an offscreen renderer (Simulator.renderer)"
        + " ".join(broken.split())[:300],
        field="simulator",
    )


def model_format(renderer: str) -> str:
    """The robot model format `renderer` draws."""
    import importlib

    return str(importlib.import_module(renderer).MODEL_FORMAT)


def run_checkpoint(run_dir: Path, config: dict[str, Any]) -> Path | None:
    """The run's final universal policy: its last backend checkpoint, else the policy it
    started from (a path, or the robot's shipped one); None when there is none."""
    found = sorted(
        (run_dir / "checkpoints").glob("backend-outer*.pt"),
        key=lambda p: int("".join(ch for ch in p.stem if ch.isdigit()) or 0),
    )
    if found:
        return found[-1]
    given = str(config.get("checkpoint") or "")
    if given and given != "none" and Path(given).is_file():
        return Path(given)
    return None


def run_policies(run_dir: Path, config: dict[str, Any]) -> tuple[dict[str, Path] | None, str]:
    """The policy each panel is drawn with, role ("best", "nominal") -> file, and a line
    naming them: the run's final universal policy for both (`run_checkpoint`), or, for a
    run without a shared policy (e.g. the BO baseline), each design's own policy saved in
    the run folder (`OWN_POLICY_FILES`, looked up by name inside it). (None, why) when the
    run kept none."""
    from coadapt_core.coadapt.specialized import OWN_POLICY_FILES
    from coadapt_core.experiments.own_policies import shares_policy

    if not shares_policy({"config": config}):
        own = {role: run_dir / name for role, name in OWN_POLICY_FILES.items()}
        if all(p.is_file() for p in own.values()):
            return own, "each design under its own policy"
        return None, (
            "the run shares no policy between designs and kept none of its best and nominal "
            "designs' own (runs made since keep them in checkpoints/policy-best.pt and "
            "policy-nominal.pt)"
        )
    checkpoint = run_checkpoint(run_dir, config)
    if checkpoint is None:
        return None, "the run kept no universal policy checkpoint"
    return {"best": checkpoint, "nominal": checkpoint}, "both under the run's final policy"


def render_run_video(
    run_dir: str | os.PathLike,
    summary: dict[str, Any],
    config: dict[str, Any],
    *,
    seconds: float = 4.0,
    width: int = 320,
    height: int = 320,
    stream: Any = None,
    progress: Any = None,
    policies: dict[str, Path] | None = None,
) -> list[Path]:
    """Roll out the best and the nominal design (one agent each, no randomization, command
    0.5 m/s forward), each under its policy (`policies`, default `run_policies`), and write
    `<run_dir>/best_vs_nominal.gif` (and `.mp4` when ffmpeg exists), each through a
    temporary file and a rename: an interrupt leaves the old file or none, never a partial
    one. Returns the files written; prints one line saying what happened. `progress(fraction,
    text)` is told each rollout and every drawn frame."""
    stream = stream or sys.stderr

    def tell(fraction: float, text: str) -> None:
        if progress is not None:
            progress(fraction, text)

    run_dir = Path(run_dir)
    want_mp4 = shutil.which("ffmpeg") is not None  # checked before any rollout
    try:
        panels, fps, why, renderer = _run_panels(run_dir, summary, config, seconds, policies, tell)
    except Exception as exc:  # the run's result stands; the picture is a bonus
        print(
            f"video: not rendered ({type(exc).__name__}: {' '.join(str(exc).split())[:160]})",
            file=stream,
        )
        return []
    if panels is None:  # a stand-in policy would mislead
        print(f"video: not rendered ({why})", file=stream)
        return []
    outputs = [run_dir / f"{VIDEO_NAME}.gif"] + (
        [run_dir / f"{VIDEO_NAME}.mp4"] if want_mp4 else []
    )
    payload = {
        "panels": panels,
        "outputs": [str(p) for p in outputs],
        "width": width,
        "height": height,
        "fps": fps,
        "report": True,
    }
    tell(0.4, "drawing frames")
    frames = sum(len(p["frames"]) for p in panels)

    def on_line(line: str) -> None:  # "frame <k>" from render_panels, one per drawn frame
        if line.startswith("frame ") and line[6:].strip().isdigit():
            k = int(line[6:])
            tell(0.4 + 0.55 * k / max(frames, 1), f"drawing frame {k}/{frames}")

    backend, errors = offscreen(
        "render_panels", payload, timeout=900, on_line=on_line, renderer=renderer
    )
    tell(1.0, "written" if backend is not None else "not rendered")
    if backend is not None:
        written = [p for p in outputs if p.is_file()]
        print(
            f"video: {', '.join(str(p) for p in written)} (best left, nominal right, {why}; "
            f"{backend})",
            file=stream,
        )
        return written
    print("video: not rendered, no offscreen GL here (" + "; ".join(errors) + ")", file=stream)
    return []


def _run_panels(
    run_dir: Path,
    summary: dict[str, Any],
    config: dict[str, Any],
    seconds: float,
    policies: dict[str, Path] | None,
    tell: Any,
) -> tuple[list[dict[str, Any]] | None, float, str, str]:
    """(the best and the nominal design's panels, frames per second, which policies drew them,
    the renderer): each design rolled out under its policy on the run's simulator; no panels
    (None) and why when the run kept no policy to draw them with."""
    from coadapt_core.plugins import get_registry

    registry = get_registry()
    # a run config without robot or simulator (older runs) means the defaults in force
    robot = registry.get("robot", config.get("robot") or registry.default("robot"))()
    why = "the policies given"
    if policies is None:
        policies, why = run_policies(run_dir, config)
    if policies is None:
        return None, 0.0, why, ""
    sim_name = config.get("sim") or registry.default("simulator")
    sim_cls = registry.get("simulator", sim_name)
    renderer = renderer_for(sim_name)
    from coadapt_core.experiments.evaluate import evaluate_checkpoint

    panels = []
    for k, (label, design) in enumerate(
        (("best", summary["best_design"]), ("nominal", summary["nominal_design"]))
    ):
        tell(0.2 * k, f"rolling out the {label} design ({seconds:g} s)")
        result = evaluate_checkpoint(
            policies[label],
            robot,
            sim_cls,
            design,
            terrain=config.get("terrain", "flat"),
            command=[0.5, 0.0, 0.0],
            agents=1,
            seconds=seconds,
            seed=int(config.get("seed") or 0),
            randomize=False,
            record=True,
        )
        trajectory = result["_trajectory"]
        panels.append(
            rollout_panel(
                robot, design, trajectory, panel_label(label, design, result["vx_mean"]), renderer
            )
        )
    return panels, 1.0 / (2 * trajectory["dt"]), why, renderer


def offscreen(
    function: str,
    kwargs: dict[str, Any],
    *,
    timeout: float,
    on_line: Any = None,
    renderer: str | None = None,
) -> tuple[str | None, list[str]]:
    """Call `<renderer>.<function>(**kwargs)` in a fresh interpreter under each of the
    renderer's `environments()` in turn (`renderer`: a module path, default `renderer_for()`).
    Returns (the label of the environment that worked, e.g. "MUJOCO_GL=egl", or None, and the
    last error line of each one tried). `on_line(text)` gets each line the function prints,
    as it prints it (progress). An interrupt stops the interpreter and removes the temporary
    files of the `outputs` it was writing."""
    import importlib
    import tempfile
    import threading

    renderer = renderer or renderer_for()
    code = (
        f"import json, sys\nfrom {renderer} import {function}\n"
        f"{function}(**json.loads(sys.stdin.read()))\n"
    )
    errors = []
    for backend, variables in importlib.import_module(renderer).environments():
        env = dict(os.environ, **variables)
        with tempfile.TemporaryFile("w+") as err:
            proc = subprocess.Popen(
                [sys.executable, "-c", code],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=err,
                text=True,
                env=env,
            )
            timer = threading.Timer(timeout, proc.kill)
            timer.start()
            try:
                assert proc.stdin is not None and proc.stdout is not None
                proc.stdin.write(json.dumps(kwargs))
                proc.stdin.close()
                for line in proc.stdout:
                    if on_line is not None:
                        on_line(line.strip())
                returncode = proc.wait()
            except BaseException:
                proc.kill()
                proc.wait()
                for output in kwargs.get("outputs") or []:
                    Path(partial_name(output)).unlink(missing_ok=True)
                raise
            finally:
                timer.cancel()
            err.seek(0)
            stderr = err.read()
        if returncode == 0:
            return backend, errors
        errors.append(f"{backend}: {(stderr.strip().splitlines() or ['no output'])[-1][:160]}")
    return None, errors


def partial_name(output: str | os.PathLike) -> str:
    """Where `output` is written before its rename (same folder, same extension)."""
    path = Path(output)
    return str(path.with_name(f".{path.stem}.partial{path.suffix}"))


def panel_label(role: str, design: Any, vx: float) -> str:
    """A panel's caption: "best: 0.53, 0.69 | vx 0.45 m/s" (a colon and a bar, not bare spaces,
    which the small bitmap font draws too narrow to see: "best0.53")."""
    values = ", ".join(f"{x:.0f}" if float(x).is_integer() else f"{x:.2f}" for x in design)
    return f"{role}: {values} | vx {vx:.2f} m/s"


def rollout_panel(
    robot: Any, design: Any, trajectory: dict, label: str | None = None, renderer: str | None = None
) -> dict[str, Any]:
    """What `render_panels` draws of one recorded rollout (`evaluate_checkpoint(record=True)`):
    the design's model in the renderer's format, every other frame (25 fps at a 0.02 s
    policy step), a label."""
    model = robot.build(robot.check_design(design) if hasattr(robot, "check_design") else design)
    text = model.text(model_format(renderer or renderer_for()))
    return {
        "model": text,
        "joint_names": model.joint_names,
        "frames": trajectory["frames"][::2],
        "label": label,
    }


def write_rollout_video(
    robot: Any, design: Any, trajectory: dict, output: Path, width: int = 480, height: int = 360
) -> tuple[str | None, list[str]]:
    """`coadapt eval --video`: one recorded rollout into `output` (.gif, or .mp4 with ffmpeg).
    Returns `offscreen`'s (backend, errors)."""
    renderer = renderer_for()
    panel = rollout_panel(robot, design, trajectory, renderer=renderer)
    payload = {
        "panels": [panel],
        "outputs": [str(output)],
        "width": width,
        "height": height,
        "fps": 1.0 / (2 * trajectory["dt"]),
    }
    return offscreen("render_panels", payload, timeout=1800, renderer=renderer)


__all__ = [
    "VIDEO_NAME",
    "model_format",
    "offscreen",
    "partial_name",
    "render_run_video",
    "renderer_for",
    "rollout_panel",
    "run_checkpoint",
    "run_policies",
    "write_rollout_video",
]
