"""Offscreen MuJoCo rendering (EGL, else OSMesa) of robot designs: a design's default pose
as a PNG (`coadapt robot render`), a recorded rollout as a GIF or MP4 (`coadapt eval
--video`), and a run's answer, the best design and the nominal one walking side by side
under the run's final policy (`coadapt run`; no GL backend there is a one-line note, never
a failed run). The camera is framed by each robot's own size, read from its model.

MuJoCo picks its GL backend when first imported, so every picture is drawn in a fresh
interpreter (`offscreen`) that tries the backends in turn."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

VIDEO_NAME = "best_vs_nominal"


def run_checkpoint(run_dir: Path, config: dict[str, Any]) -> Path | None:
    """The run's final universal policy: its last backend checkpoint, else the policy it
    started from (a path, or the robot's shipped one); None when there is none."""
    found = sorted((run_dir / "checkpoints").glob("backend-outer*.pt"),
                   key=lambda p: int("".join(ch for ch in p.stem if ch.isdigit()) or 0))
    if found:
        return found[-1]
    given = str(config.get("checkpoint") or "")
    if given and given != "none" and Path(given).is_file():
        return Path(given)
    return None


def render_run_video(
    run_dir: str | os.PathLike, summary: dict[str, Any], config: dict[str, Any], *, seconds: float = 4.0,
    width: int = 320, height: int = 320, stream: Any = None, progress: Any = None,
) -> list[Path]:
    """Roll out the best and the nominal design (one agent each, no randomization, command
    0.5 m/s forward) and write `<run_dir>/best_vs_nominal.gif` (and `.mp4` when ffmpeg
    exists), each through a temporary file and a rename: an interrupt leaves the old file or
    none, never a partial one. Returns the files written; prints one line saying what
    happened. `progress(fraction, text)` is told each rollout and every drawn frame."""
    stream = stream or sys.stderr

    def tell(fraction: float, text: str) -> None:
        if progress is not None:
            progress(fraction, text)

    run_dir = Path(run_dir)
    want_mp4 = shutil.which("ffmpeg") is not None  # checked before any rollout
    try:
        from coadapt_core.plugins import get_registry

        registry = get_registry()
        # a run config without robot or simulator (older runs) means the defaults in force
        robot = registry.get("robot", config.get("robot") or registry.default("robot"))()
        checkpoint = run_checkpoint(run_dir, config)
        if checkpoint is None:  # e.g. bo-specialized keeps no policy; a stand-in would mislead
            print("video: not rendered (the run kept no universal policy checkpoint)", file=stream)
            return []
        sim_cls = registry.get("simulator", config.get("sim") or registry.default("simulator"))
        from coadapt_core.experiments.evaluate import evaluate_checkpoint

        panels = []
        for k, (label, design) in enumerate((("best", summary["best_design"]), ("nominal", summary["nominal_design"]))):
            tell(0.2 * k, f"rolling out the {label} design ({seconds:g} s)")
            result = evaluate_checkpoint(
                checkpoint, robot, sim_cls, design, terrain=config.get("terrain", "flat"), command=[0.5, 0.0, 0.0],
                agents=1, seconds=seconds, seed=int(config.get("seed") or 0), randomize=False, record=True,
            )
            trajectory = result["_trajectory"]
            panels.append(rollout_panel(robot, design, trajectory, f"{label} " + ", ".join(
                f"{x:.0f}" if float(x).is_integer() else f"{x:.2f}" for x in design) + f"  vx {result['vx_mean']:.2f} m/s"))
        fps = 1.0 / (2 * trajectory["dt"])
    except Exception as exc:  # the run's result stands; the picture is a bonus
        print(f"video: not rendered ({type(exc).__name__}: {' '.join(str(exc).split())[:160]})", file=stream)
        return []
    outputs = [run_dir / f"{VIDEO_NAME}.gif"] + ([run_dir / f"{VIDEO_NAME}.mp4"] if want_mp4 else [])
    payload = {"panels": panels, "outputs": [str(p) for p in outputs], "width": width, "height": height, "fps": fps,
               "report": True}
    tell(0.4, "drawing frames")
    frames = sum(len(p["frames"]) for p in panels)

    def on_line(line: str) -> None:  # "frame <k>" from render_panels, one per drawn frame
        if line.startswith("frame ") and line[6:].strip().isdigit():
            k = int(line[6:])
            tell(0.4 + 0.55 * k / max(frames, 1), f"drawing frame {k}/{frames}")

    backend, errors = offscreen("render_panels", payload, timeout=900, on_line=on_line)
    tell(1.0, "written" if backend is not None else "not rendered")
    if backend is not None:
        written = [p for p in outputs if p.is_file()]
        print(f"video: {', '.join(str(p) for p in written)} (best left, nominal right; MUJOCO_GL={backend})", file=stream)
        return written
    print("video: not rendered, no offscreen GL here (" + "; ".join(errors) + ")", file=stream)
    return []


#: GL backends tried in turn for offscreen rendering (MUJOCO_GL), unless MUJOCO_GL is set
GL_BACKENDS = ("egl", "osmesa")


def offscreen(function: str, kwargs: dict[str, Any], *, timeout: float,
              on_line: Any = None) -> tuple[str | None, list[str]]:
    """Call `coadapt_core.viz.video.<function>(**kwargs)` in a fresh interpreter under each GL
    backend in turn (MUJOCO_GL when set). Returns (the backend that worked, or None, and
    the last error line of each backend tried). `on_line(text)` gets each line the function
    prints, as it prints it (progress). An interrupt stops the interpreter and removes the
    temporary files of the `outputs` it was writing."""
    import tempfile
    import threading

    code = f"import json, sys\nfrom coadapt_core.viz.video import {function}\n{function}(**json.loads(sys.stdin.read()))\n"
    backends = [os.environ["MUJOCO_GL"]] if os.environ.get("MUJOCO_GL") else list(GL_BACKENDS)
    errors = []
    for backend in backends:
        env = dict(os.environ, MUJOCO_GL=backend, PYOPENGL_PLATFORM=backend)
        with tempfile.TemporaryFile("w+") as err:
            proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                    stderr=err, text=True, env=env)
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


def rollout_panel(robot: Any, design: Any, trajectory: dict, label: str | None = None) -> dict[str, Any]:
    """What `render_panels` draws of one recorded rollout (`evaluate_checkpoint(record=True)`):
    the design's model, every other frame (25 fps at a 0.02 s policy step), a label."""
    model = robot.build(robot.check_design(design) if hasattr(robot, "check_design") else design)
    return {"mjcf": model.mjcf, "joint_names": model.joint_names, "frames": trajectory["frames"][::2], "label": label}


def write_rollout_video(robot: Any, design: Any, trajectory: dict, output: Path, width: int = 480,
                        height: int = 360) -> tuple[str | None, list[str]]:
    """`coadapt eval --video`: one recorded rollout into `output` (.gif, or .mp4 with ffmpeg).
    Returns `offscreen`'s (backend, errors)."""
    panel = rollout_panel(robot, design, trajectory)
    payload = {"panels": [panel], "outputs": [str(output)], "width": width, "height": height,
               "fps": 1.0 / (2 * trajectory["dt"])}
    return offscreen("render_panels", payload, timeout=1800)


#: shadow map side, texels: with MuJoCo's default 4096 a 320 x 320 frame took 0.22 s to render
#: in software (EGL without a GPU), with 1024 0.08-0.13 s, and the shadows still show
SHADOW_SIZE = 1024


def camera_for(model: Any, data: Any) -> tuple[float, float]:
    """(camera distance, look-at height) from the robot's own size: the height of its
    bodies' bounding spheres above the floor at the first frame (never a fixed 1.6 m)."""
    import numpy as np

    mask = model.geom_type != 0  # not the floor plane
    top = float(np.max(data.geom_xpos[mask, 2] + model.geom_rbound[mask]))
    bottom = float(np.min(data.geom_xpos[mask, 2] - model.geom_rbound[mask]))
    height = max(top - min(bottom, 0.0), 0.1)
    return 1.9 * height + 0.4, 0.5 * height


def scene_model(mjcf: str, width: int, height: int, *, floor: float = 20.0, texrepeat: int = 40,
                lights: tuple[tuple[tuple[float, float, float], tuple[float, float, float], float], ...] = (
                    ((0.0, -2.0, 4.0), (0.0, 0.4, -1.0), 0.8),),
                floor_collides: bool = True, shadow_size: int = SHADOW_SIZE) -> Any:
    """The design's MJCF with a checkered floor (half size `floor` m) and lights ((pos, dir,
    diffuse) each), compiled for offscreen frames of `width` x `height` (shared by
    `coadapt robot render`, `coadapt eval --video` and the run's best-vs-nominal GIF), with a
    `shadow_size` texel shadow map (at least twice the frame's larger side)."""
    import mujoco

    spec = mujoco.MjSpec.from_string(mjcf)
    texture = spec.add_texture(name="grid", type=mujoco.mjtTexture.mjTEXTURE_2D,
                               builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, rgb1=[0.82, 0.84, 0.86],
                               rgb2=[0.68, 0.7, 0.72], width=256, height=256)
    material = spec.add_material(name="grid", texrepeat=[texrepeat, texrepeat], reflectance=0.05)
    material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = texture.name
    plane = spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[floor, floor, 0.05],
                                    material="grid")
    if not floor_collides:
        plane.contype, plane.conaffinity = 0, 0
    for pos, direction, diffuse in lights:
        spec.worldbody.add_light(pos=list(pos), dir=list(direction), diffuse=[diffuse] * 3)
    model = spec.compile()
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    model.vis.quality.shadowsize = max(int(shadow_size), 2 * max(width, height))
    return model


def render_pose_png(mjcf: str, qpos_joints: list[float], base_height: float, output: str, width: int, height: int) -> None:
    """Draw the robot at the given pose, standing on a checker floor, into a PNG (run through
    `offscreen`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.image
    import mujoco

    model = scene_model(mjcf, width, height, floor=4.0, texrepeat=8, floor_collides=False,
                        lights=(((1.5, -1.5, 3.5), (-0.4, 0.4, -1.0), 0.8), ((-2.0, 2.0, 3.0), (0.5, -0.5, -1.0), 0.4)))
    data = mujoco.MjData(model)
    data.qpos[2] = base_height
    data.qpos[3:7] = [1, 0, 0, 0]
    data.qpos[7 : 7 + len(qpos_joints)] = qpos_joints
    mujoco.mj_forward(model, data)
    camera = mujoco.MjvCamera()
    top = float(max(data.geom_xpos[:, 2].max(), base_height))
    camera.lookat[:] = [0.0, 0.0, 0.5 * top]
    camera.distance = 1.4 + 1.6 * top
    camera.azimuth, camera.elevation = 140.0, -12.0
    options = mujoco.MjvOption()
    options.geomgroup[:] = 1  # collision shapes and visual-only geoms
    with mujoco.Renderer(model, height, width) as renderer:
        renderer.update_scene(data, camera=camera, scene_option=options)
        pixels = renderer.render()
    matplotlib.image.imsave(output, pixels)


def render_panels(panels: list[dict], outputs: list[str], width: int, height: int, fps: float,
                  report: bool = False) -> None:
    """Replay each panel's base poses and joint angles in its own MuJoCo model, offscreen,
    and write the panels side by side, one frame per recorded step (the shorter rollout
    holds its last frame). Runs in a fresh interpreter: MUJOCO_GL is read at import."""
    import mujoco
    import numpy as np
    from PIL import Image, ImageDraw

    rendered = []
    for panel in panels:
        model = scene_model(panel["mjcf"], width, height)
        data = mujoco.MjData(model)
        addresses = [model.jnt_qposadr[model.joint(name).id] for name in panel["joint_names"]]
        camera = mujoco.MjvCamera()
        camera.azimuth, camera.elevation = 90.0, -10.0
        images = []
        with mujoco.Renderer(model, height, width) as renderer:
            for k, frame in enumerate(panel["frames"]):
                data.qpos[0:3] = frame["pos"]
                data.qpos[3:7] = frame["quat"]
                data.qpos[addresses] = frame["q"]
                mujoco.mj_forward(model, data)
                if k == 0:
                    distance, look_z = camera_for(model, data)
                    camera.distance = distance
                camera.lookat[:] = [frame["pos"][0], frame["pos"][1], look_z]
                renderer.update_scene(data, camera=camera)
                image = Image.fromarray(np.array(renderer.render()))
                if panel.get("label"):  # readable on the dark sky and the floor
                    ImageDraw.Draw(image).text((6, 6), panel["label"], fill=(255, 255, 255), stroke_width=1,
                                               stroke_fill=(0, 0, 0))
                images.append(np.array(image))
                if report:
                    print(f"frame {sum(map(len, rendered)) + len(images)}", flush=True)
        rendered.append(images)
    n = max(len(images) for images in rendered)
    frames = [np.concatenate([images[min(i, len(images) - 1)] for images in rendered], axis=1) for i in range(n)]
    for output in outputs:
        partial = partial_name(output)  # renamed once whole: an interrupt never leaves half a file
        if output.endswith(".gif"):
            pil = [Image.fromarray(f) for f in frames]
            pil[0].save(partial, format="GIF", save_all=True, append_images=pil[1:], duration=int(1000 / fps), loop=0)
            os.replace(partial, output)
        else:
            proc = subprocess.run(
                ["ffmpeg", "-y", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgb24",
                 "-s", f"{frames[0].shape[1]}x{frames[0].shape[0]}", "-r", str(fps), "-i", "-", "-pix_fmt", "yuv420p",
                 "-f", "mp4", partial],
                input=np.stack(frames).tobytes(), capture_output=True,
            )
            if proc.returncode != 0:
                Path(partial).unlink(missing_ok=True)
                raise RuntimeError(proc.stderr.decode().strip().splitlines()[-1])
            os.replace(partial, output)


__all__ = [
    "GL_BACKENDS", "VIDEO_NAME", "camera_for", "offscreen", "render_panels", "render_pose_png", "render_run_video",
    "rollout_panel", "run_checkpoint", "scene_model", "write_rollout_video",
]
