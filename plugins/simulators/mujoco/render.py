"""The MuJoCo simulator's offscreen renderer (EGL, else OSMesa): a design's default pose as a
PNG (`coadapt robot render`) and recorded rollouts side by side as a GIF or MP4 (`coadapt
eval --video`, a run's best-vs-nominal GIF). The simulator declares this module as its
`renderer`; `coadapt_core.viz.video.offscreen` runs its functions in a fresh interpreter
under each environment of `environments()` in turn (MuJoCo picks its GL backend when first
imported, so nothing here imports mujoco at module level). The camera is framed by each
robot's own size, read from its model."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path
from typing import Any

from coadapt_core.viz.video import partial_name

#: the robot model format the renderer draws (`RobotModel.formats` key)
MODEL_FORMAT = "mjcf"
#: GL backends tried in turn for offscreen rendering (MUJOCO_GL), unless MUJOCO_GL is set
GL_BACKENDS = ("egl", "osmesa")


def environments() -> list[tuple[str, dict[str, str]]]:
    """(label, environment variables) to try in turn: MUJOCO_GL when set, else each of
    GL_BACKENDS."""
    backends = [os.environ["MUJOCO_GL"]] if os.environ.get("MUJOCO_GL") else list(GL_BACKENDS)
    return [(f"MUJOCO_GL={b}", {"MUJOCO_GL": b, "PYOPENGL_PLATFORM": b}) for b in backends]


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


def scene_model(
    mjcf: str,
    width: int,
    height: int,
    *,
    floor: float = 20.0,
    texrepeat: int = 40,
    lights: tuple[tuple[tuple[float, float, float], tuple[float, float, float], float], ...] = (
        ((0.0, -2.0, 4.0), (0.0, 0.4, -1.0), 0.8),
    ),
    floor_collides: bool = True,
    shadow_size: int = SHADOW_SIZE,
) -> Any:
    """The design's MJCF with a checkered floor (half size `floor` m) and lights ((pos, dir,
    diffuse) each), compiled for offscreen frames of `width` x `height` (shared by
    `coadapt robot render`, `coadapt eval --video` and the run's best-vs-nominal GIF), with a
    `shadow_size` texel shadow map (at least twice the frame's larger side)."""
    import mujoco

    spec = mujoco.MjSpec.from_string(mjcf)
    texture = spec.add_texture(
        name="grid",
        type=mujoco.mjtTexture.mjTEXTURE_2D,
        builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
        rgb1=[0.82, 0.84, 0.86],
        rgb2=[0.68, 0.7, 0.72],
        width=256,
        height=256,
    )
    material = spec.add_material(name="grid", texrepeat=[texrepeat, texrepeat], reflectance=0.05)
    material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = texture.name
    plane = spec.worldbody.add_geom(
        name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[floor, floor, 0.05], material="grid"
    )
    if not floor_collides:
        plane.contype, plane.conaffinity = 0, 0
    for pos, direction, diffuse in lights:
        spec.worldbody.add_light(pos=list(pos), dir=list(direction), diffuse=[diffuse] * 3)
    model = spec.compile()
    model.vis.global_.offwidth = max(model.vis.global_.offwidth, width)
    model.vis.global_.offheight = max(model.vis.global_.offheight, height)
    model.vis.quality.shadowsize = max(int(shadow_size), 2 * max(width, height))
    return model


def render_pose_png(
    model: str, qpos_joints: list[float], base_height: float, output: str, width: int, height: int
) -> None:
    """Draw the robot at the given pose, standing on a checker floor, into a PNG (run through
    `offscreen`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.image
    import mujoco

    mjcf = model
    model = scene_model(
        mjcf,
        width,
        height,
        floor=4.0,
        texrepeat=8,
        floor_collides=False,
        lights=(
            ((1.5, -1.5, 3.5), (-0.4, 0.4, -1.0), 0.8),
            ((-2.0, 2.0, 3.0), (0.5, -0.5, -1.0), 0.4),
        ),
    )
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


def render_panels(
    panels: list[dict],
    outputs: list[str],
    width: int,
    height: int,
    fps: float,
    report: bool = False,
) -> None:
    """Replay each panel's base poses and joint angles in its own MuJoCo model, offscreen,
    and write the panels side by side, one frame per recorded step (the shorter rollout
    holds its last frame). Runs in a fresh interpreter: MUJOCO_GL is read at import."""
    import numpy as np

    rendered = []
    for panel in panels:
        done = sum(map(len, rendered))
        rendered.append(_render_panel(panel, width, height, done if report else None))
    n = max(len(images) for images in rendered)
    frames = [
        np.concatenate([images[min(i, len(images) - 1)] for images in rendered], axis=1)
        for i in range(n)
    ]
    for output in outputs:
        _write_frames(frames, output, fps)


def _render_panel(panel: dict, width: int, height: int, report_from: int | None) -> list:
    """One panel's frames [H, W, 3] as uint8 arrays; with `report_from`, a "frame N" line
    per frame, counted on from the frames of the panels before."""
    import mujoco
    import numpy as np
    from PIL import Image, ImageDraw

    model = scene_model(panel["model"], width, height)
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
                ImageDraw.Draw(image).text(
                    (6, 6),
                    panel["label"],
                    fill=(255, 255, 255),
                    stroke_width=1,
                    stroke_fill=(0, 0, 0),
                )
            images.append(np.array(image))
            if report_from is not None:
                print(f"frame {report_from + len(images)}", flush=True)
    return images


def _write_frames(frames: list, output: str, fps: float) -> None:
    """Write the frames as a GIF or (through ffmpeg) an MP4 at `output`; the file appears
    only once whole (an interrupt never leaves half a file)."""
    import numpy as np
    from PIL import Image

    partial = partial_name(output)
    if output.endswith(".gif"):
        pil = [Image.fromarray(f) for f in frames]
        pil[0].save(
            partial,
            format="GIF",
            save_all=True,
            append_images=pil[1:],
            duration=int(1000 / fps),
            loop=0,
        )
        os.replace(partial, output)
        return
    proc = subprocess.run(
        [
            "ffmpeg",
            "-y",
            "-loglevel",
            "error",
            "-f",
            "rawvideo",
            "-pix_fmt",
            "rgb24",
            "-s",
            f"{frames[0].shape[1]}x{frames[0].shape[0]}",
            "-r",
            str(fps),
            "-i",
            "-",
            "-pix_fmt",
            "yuv420p",
            "-f",
            "mp4",
            partial,
        ],
        input=np.stack(frames).tobytes(),
        capture_output=True,
    )
    if proc.returncode != 0:
        Path(partial).unlink(missing_ok=True)
        raise RuntimeError(proc.stderr.decode().strip().splitlines()[-1])
    os.replace(partial, output)
