"""Four-bar legs as `robot new` finds them in a model file (`new`) and writes them as spec
`loops` (`loops`).

Two leg chains are the open halves of one four-bar leg when their first hinges turn about
one axis side by side on one side of the base (each the other's nearest leg: a biped's hips
are coaxial too, on either side of the base) and their ends meet at the model's zero pose
(PyBullet's minitaurs: each leg two motors on one axis turning an upper and a lower leg,
straight up at zero, the lower legs' ends together; PyBullet's minitaur environment pins
them in code). Such a pair is one leg: its end (`loop_tip`, on the lower leg's axis at its
far end, a `tips` foot on each half) is pinned, the first hinge of each half is a motor and
the others are passive (`loops.passive`), its foot is the first half's tip and its hip the
first half's motor body. Its standing pose (`four_bar_pose`): the toe under the motor axis
at STAND_SHARE of the leg's length (upper plus lower leg), each half solved to it with its
knee out on its own side (the diamond the real robot stands in). Coaxial halves whose ends
do not meet, or meet only short of one half's end, are refused in one line.
"""

from __future__ import annotations

import mujoco
import numpy as np
from coadapt_plugins.robots.specs.orient import TIP_RADIUS, _geom_points

from coadapt_core.errors import UserError

#: two legs whose first hinges share an axis line (within this share of their distance) and
#: are each other's nearest turn side by side on one axis
FOUR_BAR_SHARE = 0.05
#: their ends meet when nearer than this share of the first's reach from its motor axis,
#: and nearer than PIN_SHARE of it across the axis (in the legs' plane): a pin short of one
#: half's end (its lower leg reaching on past it, minitaur_derpy's) is not placed
MEET_SHARE = 0.1
PIN_SHARE = 0.02
#: the seeds (motor, knee) of each half's standing solve, rad
SEEDS = [(m, k) for m in (np.pi / 2, -np.pi / 2) for k in (2.0, -2.0)]


def _hinges_on(model: mujoco.MjModel, chain: list[int]) -> list[int]:
    return [
        j
        for b in chain
        for j in range(model.njnt)
        if model.jnt_bodyid[j] == b and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
    ]


def loop_tip(model: mujoco.MjModel, body: int) -> np.ndarray | None:
    """The point of `body` (its frame) where a four-bar's pin goes: on the line from its
    origin through the centre of its collision geoms, at their far end less TIP_RADIUS (the
    tip sphere's centre); None without collision geoms."""
    geoms = [
        g
        for g in range(model.ngeom)
        if model.geom_bodyid[g] == body and (model.geom_contype[g] or model.geom_conaffinity[g])
    ]
    if not geoms:
        return None
    points = np.concatenate([_geom_points(model, g) for g in geoms])
    centre = points.mean(axis=0)
    if np.linalg.norm(centre) < 1e-9:
        return None
    u = centre / np.linalg.norm(centre)
    return u * (float(np.max(points @ u)) - TIP_RADIUS)


def _world_tip(model, data, body: int) -> np.ndarray:
    tip = loop_tip(model, body)
    local = np.zeros(3) if tip is None else tip
    return data.xpos[body] + data.xmat[body].reshape(3, 3) @ local


def four_bars(model: mujoco.MjModel, data, base: int, legs: list[dict]) -> list[tuple[int, int]]:
    """The pairs (a, b) of `legs` (indices, a first) that are the halves of one four-bar
    leg (module docstring); one line for coaxial halves whose ends do not meet. `data`
    holds the model's zero pose, kinematics done."""
    first = [_hinges_on(model, g["chain"])[0] for g in legs]
    frame = data.xmat[base].reshape(3, 3)
    anchors = data.xanchor[first]
    side = np.sign((anchors - data.xpos[base]) @ frame[:, 1])  # left (+) or right of the base
    gaps = np.linalg.norm(anchors[:, None] - anchors[None], axis=-1) + np.diag(
        np.full(len(legs), np.inf)
    )
    pairs = []
    for a in range(len(legs)):
        b = int(np.argmin(gaps[a]))
        if b <= a or int(np.argmin(gaps[b])) != a or side[a] != side[b]:
            continue
        axis, gap = data.xaxis[first[a]], anchors[b] - anchors[a]
        off_axis = float(np.linalg.norm(gap - (gap @ axis) * axis))
        if abs(axis @ data.xaxis[first[b]]) <= 0.99 or off_axis >= FOUR_BAR_SHARE * gaps[a, b]:
            continue
        ends = [_world_tip(model, data, legs[k]["foot"]) for k in (a, b)]
        reach = float(np.linalg.norm(ends[0] - anchors[a]))
        apart = float(np.linalg.norm(ends[0] - ends[1]))
        across = ends[1] - ends[0] - ((ends[1] - ends[0]) @ axis) * axis
        if np.linalg.norm(across) > PIN_SHARE * reach:
            raise UserError(
                f"legs ending in '{model.body(legs[a]['foot']).name}' and "
                f"'{model.body(legs[b]['foot']).name}' are the two halves of a four-bar leg "
                f"whose ends are {np.linalg.norm(across):.3g} m apart along the legs at the "
                "model's zero pose: its pin lies short of one half's end, which robot new does "
                "not place; write a robot plugin for it (docs/plugins.md)",
                field="model",
            )
        if apart > MEET_SHARE * reach:
            raise UserError(
                f"legs ending in '{model.body(legs[a]['foot']).name}' and "
                f"'{model.body(legs[b]['foot']).name}' turn about one axis {gaps[a, b]:.3g} m "
                f"apart: the two halves of a four-bar leg, but their ends are {apart:.3g} m "
                "apart at the model's zero pose (robot new pins them where they meet); give "
                "spec loops by hand or write a robot plugin (docs/plugins.md)",
                field="model",
            )
        pairs.append((a, b))
    return pairs


def _solve_half(model, data, hinges: list[int], foot: int, target, seed) -> tuple:
    """(angles of `hinges`, the in-plane miss) putting `foot`'s origin nearest `target`
    (Gauss-Newton from `seed`; the other joints as `data` holds them)."""
    adr = [int(model.jnt_qposadr[j]) for j in hinges]
    dof = [int(model.jnt_dofadr[j]) for j in hinges]
    data.qpos[adr] = seed
    for _ in range(100):
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        jac = np.zeros((3, model.nv))
        mujoco.mj_jacBody(model, data, jac, None, foot)
        miss = target - data.xpos[foot]
        step = np.linalg.lstsq(jac[:, dof], miss, rcond=1e-10)[0]
        data.qpos[adr] += np.clip(step, -0.5, 0.5)
        if np.max(np.abs(step)) < 1e-12:
            break
    mujoco.mj_kinematics(model, data)
    axis = data.xaxis[hinges[0]]
    miss = target - data.xpos[foot]
    angles = (data.qpos[adr] + np.pi) % (2 * np.pi) - np.pi
    return angles, float(np.linalg.norm(miss - (miss @ axis) * axis))


def four_bar_pose(model, legs: list[dict], pairs, share: float) -> dict[str, float]:
    """{hinge: angle} of each four-bar's halves (their tips' bodies the feet) standing with
    the toe under the motor axis at `share` of the leg's length, knees apart (module
    docstring); one line when a half cannot reach it."""
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0
    mujoco.mj_kinematics(model, data)
    pose: dict[str, float] = {}
    for a, b in pairs:
        halves = [(legs[k]["foot"], _hinges_on(model, legs[k]["chain"])) for k in (a, b)]
        motor, knee = halves[0][1][0], halves[0][1][1]
        axis, centre = data.xaxis[motor], data.xanchor[motor]
        upper = data.xanchor[knee] - centre
        lower = data.xpos[halves[0][0]] - data.xanchor[knee]
        length = sum(float(np.linalg.norm(v - (v @ axis) * axis)) for v in (upper, lower))
        tips = [data.xpos[foot].copy() for foot, _ in halves]
        along = (tips[0] - centre) @ axis
        down = np.array([0.0, 0.0, -1.0]) - axis[2] * axis  # straight down in the leg's plane
        target = centre + along * axis + share * length * down / np.linalg.norm(down)
        found = []
        for (foot, hinges), offset in zip(halves, (0.0, tips[1] - tips[0]), strict=True):
            options = []
            for seed in SEEDS:
                angles, miss = _solve_half(model, data, hinges[:2], foot, target + offset, seed)
                if miss < 1e-4 * length:  # the knee axis may lean off the motor axis
                    knee_at = data.xanchor[hinges[1]].copy()
                    options.append((angles, knee_at))
            if not options:
                raise UserError(
                    f"the four-bar leg ending in '{model.body(foot).name}' cannot put its toe "
                    f"{share:g} of its length under its motor axis",
                    field="model",
                )
            found.append((hinges[:2], options))
        (ha, oa), (hb, ob) = found
        # knees apart (a diamond); of the two diamonds, the outer half's knee behind, so
        # mirror-image legs stand as mirror images
        outer = 0 if abs(data.xanchor[ha[0]][1]) >= abs(data.xanchor[hb[0]][1]) else 1
        best = max(
            ((x, y) for x in oa for y in ob),
            key=lambda xy: (
                round(float(np.linalg.norm(xy[0][1] - xy[1][1])), 4),
                -float(xy[outer][1][0]),
            ),
        )
        for hinges, (angles, _) in zip((ha, hb), best, strict=True):
            for j, angle in zip(hinges, angles, strict=True):
                pose[model.joint(j).name] = round(float(angle), 6) + 0.0
        data.qpos[:] = model.qpos0
    return pose


def loop_entries(model, legs: list[dict], pairs) -> tuple[list[dict], list[str]]:
    """(the spec's `loops`, the passive hinges in model order): each pair's feet pinned,
    every hinge of each half after its first passive."""
    loops, passive = [], set()
    for a, b in pairs:
        knees = [
            model.joint(j).name for k in (a, b) for j in _hinges_on(model, legs[k]["chain"])[1:]
        ]
        passive.update(knees)
        loops.append(
            {"bodies": [model.body(legs[k]["foot"]).name for k in (a, b)], "passive": knees}
        )
    order = [model.joint(j).name for j in range(model.njnt)]
    return loops, [j for j in order if j in passive]
