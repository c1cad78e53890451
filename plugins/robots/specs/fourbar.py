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


def _pin_of(model, foot: int, pinned: dict) -> int | None:
    """The `pins` body on a foot's lower leg (`pinned`: lower leg -> pin body), else None."""
    lower = model.body(int(model.body_parentid[foot])).name
    name = pinned.get(model.body(foot).name) or pinned.get(lower)
    return None if name is None else model.body(name).id


def four_bars(model, data, base: int, legs: list[dict], pinned: dict | None = None) -> list:
    """The triples (a, b, pin) of `legs` (indices) that are the halves of one four-bar leg
    (module docstring): a the outer half (or the one a `pins` body is on), its end the toe;
    b's end pinned to a at `pin` (a point in a's foot body's frame where b's end meets it,
    when that is short of a's end: the longer half's lower leg reaches on past the pin) or
    at a's end (None); with `pinned` (lower leg -> its `pins` body) a pinned half's end
    meets at its pin body. One line for coaxial halves whose ends do not meet. `data` holds
    the model's zero pose, kinematics done."""
    pinned = pinned or {}
    first = [_hinges_on(model, g["chain"])[0] for g in legs]
    frame = data.xmat[base].reshape(3, 3)
    anchors = data.xanchor[first]
    side = np.sign((anchors - data.xpos[base]) @ frame[:, 1])  # left (+) or right of the base
    gaps = np.linalg.norm(anchors[:, None] - anchors[None], axis=-1) + np.diag(
        np.full(len(legs), np.inf)
    )
    found = []
    for a in range(len(legs)):
        b = int(np.argmin(gaps[a]))
        if b <= a or int(np.argmin(gaps[b])) != a or side[a] != side[b]:
            continue
        axis, gap = data.xaxis[first[a]], anchors[b] - anchors[a]
        off_axis = float(np.linalg.norm(gap - (gap @ axis) * axis))
        if abs(axis @ data.xaxis[first[b]]) <= 0.99 or off_axis >= FOUR_BAR_SHARE * gaps[a, b]:
            continue
        pins = [_pin_of(model, legs[k]["foot"], pinned) for k in (a, b)]
        outer = abs((anchors[b] - data.xpos[base]) @ frame[:, 1]) > abs(
            (anchors[a] - data.xpos[base]) @ frame[:, 1]
        )
        if pins[1] is not None or (pins[0] is None and outer):  # the outer half first
            a, b, pins = b, a, pins[::-1]
        ends = [
            data.xpos[pin] if pin is not None else _world_tip(model, data, legs[k]["foot"])
            for k, pin in zip((a, b), pins, strict=True)
        ]
        reach = float(np.linalg.norm(ends[0] - anchors[a]))
        apart = float(np.linalg.norm(ends[0] - ends[1]))
        if apart > MEET_SHARE * reach:
            raise UserError(
                f"legs ending in '{model.body(legs[a]['foot']).name}' and "
                f"'{model.body(legs[b]['foot']).name}' turn about one axis {gaps[a, b]:.3g} m "
                f"apart: the two halves of a four-bar leg, but their ends are {apart:.3g} m "
                "apart at the model's zero pose (robot new pins them where they meet); give "
                "spec loops by hand or write a robot plugin (docs/plugins.md)",
                field="model",
            )
        across = ends[1] - ends[0] - ((ends[1] - ends[0]) @ axis) * axis
        pin = None
        if np.linalg.norm(across) > PIN_SHARE * reach:  # one lower leg reaches on past the pin
            if np.linalg.norm(ends[1] - anchors[b]) > reach:
                a, b, ends = b, a, ends[::-1]
            foot = legs[a]["foot"]
            local = data.xmat[foot].reshape(3, 3).T @ (ends[1] - data.xpos[foot])
            u = loop_tip(model, foot)
            u = u / np.linalg.norm(u)
            pin = u * float(local @ u)  # on the longer lower leg's line, where b's end meets
        found.append((a, b, pin))
    return found


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


def _options(model, data, foot, hinges, target, length) -> list:
    """[(angles, knee anchor, the world of every body)] of each seed's solve putting `foot`
    at `target`."""
    out = []
    for seed in SEEDS:
        angles, miss = _solve_half(model, data, hinges[:2], foot, target, seed)
        if miss < 1e-4 * length:  # the knee axis may lean off the motor axis
            out.append((angles, data.xanchor[hinges[1]].copy(), data.xpos.copy()))
    if not out:
        raise UserError(
            f"the four-bar leg ending in '{model.body(foot).name}' cannot put its toe "
            "under its motor axis at the standing share of its length",
            field="model",
        )
    return out


def four_bar_pose(model, legs: list[dict], pairs, share: float, pinned=None) -> dict:
    """{hinge: angle} of each four-bar's halves (their tips' bodies the feet) standing with
    the toe under the motor axis at `share` of the leg's length, the other half's end where
    the first puts the pin, knees apart (module docstring); one line when a half cannot reach
    it. `pinned` as `four_bars` takes it."""
    pinned = pinned or {}
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0
    mujoco.mj_kinematics(model, data)
    pose: dict[str, float] = {}
    for a, b, _ in pairs:
        (fa, ha), (fb, hb) = [
            (legs[k]["foot"], _hinges_on(model, legs[k]["chain"])) for k in (a, b)
        ]
        pin = _pin_of(model, fa, pinned)
        pin = fa if pin is None else pin
        axis, centre = data.xaxis[ha[0]], data.xanchor[ha[0]]
        upper = data.xanchor[ha[1]] - centre
        lower = data.xpos[fa] - data.xanchor[ha[1]]
        length = sum(float(np.linalg.norm(v - (v @ axis) * axis)) for v in (upper, lower))
        offset = data.xpos[fb] - data.xpos[pin]  # along the axis: where b's end meets the pin
        along = (data.xpos[fa] - centre) @ axis
        down = np.array([0.0, 0.0, -1.0]) - axis[2] * axis  # straight down in the leg's plane
        target = centre + along * axis + share * length * down / np.linalg.norm(down)
        combos = []
        for first in _options(model, data, fa, ha, target, length):
            for second in _options(model, data, fb, hb, first[2][pin] + offset, length):
                combos.append((first, second))
            data.qpos[:] = model.qpos0
        # knees apart (a diamond); of the two diamonds, the outer half's knee behind, so
        # mirror-image legs stand as mirror images
        outer = 0 if abs(centre[1]) >= abs(data.xanchor[hb[0]][1]) else 1
        best = max(
            combos,
            key=lambda xy: (
                round(float(np.linalg.norm(xy[0][1] - xy[1][1])), 4),
                -float(xy[outer][1][0]),
            ),
        )
        for hinges, (angles, _, _) in zip((ha, hb), best, strict=True):
            for j, angle in zip(hinges[:2], angles, strict=True):
                pose[model.joint(j).name] = round(float(angle), 6) + 0.0
        data.qpos[:] = model.qpos0
        mujoco.mj_kinematics(model, data)
    return pose


def loop_entries(model, legs: list[dict], pairs, pinned=None) -> tuple[list[dict], list[str]]:
    """(the spec's `loops`, the passive hinges in model order): each pair's first half's pin
    (its `pins` body, else its foot) pinned to the second's foot, every hinge of each half
    after its first passive."""
    loops, passive = [], set()
    for a, b, _ in pairs:
        knees = [
            model.joint(j).name for k in (a, b) for j in _hinges_on(model, legs[k]["chain"])[1:]
        ]
        passive.update(knees)
        pin = _pin_of(model, legs[a]["foot"], pinned or {})
        first = legs[a]["foot"] if pin is None else pin
        loops.append(
            {"bodies": [model.body(first).name, model.body(legs[b]["foot"]).name], "passive": knees}
        )
    order = [model.joint(j).name for j in range(model.njnt)]
    return loops, [j for j in order if j in passive]


def four_bar_legs(
    model, legs, pairs, pinned, params, notes, comments
) -> tuple[dict, list[str], list]:
    """(the spec's standing pose, each leg's hip (its first half's motor body), the legs:
    each pair's first half) of four-bar legs, with `robot new`'s comments and note. The pose
    is solved again at each design (`solve`: the toes as deep under the hips, as a share of
    the legs' scaled links, as at the nominal design)."""
    from coadapt_plugins.robots.specs.stand import STAND_SHARE, _leg_length

    joints = four_bar_pose(model, legs, pairs, STAND_SHARE, pinned)
    hips = [model.body(int(model.jnt_bodyid[model.joint(_first(model, legs[a])).id])).name
            for a, _, _ in pairs]  # fmt: skip
    data = mujoco.MjData(model)
    data.qpos[:] = model.qpos0
    for name, angle in joints.items():
        data.qpos[model.jnt_qposadr[model.joint(name).id]] = angle
    mujoco.mj_kinematics(model, data)
    shares = [
        (data.xpos[model.body(hip).id][2] - data.xpos[legs[a]["foot"]][2])
        / _leg_length(model, legs[a], params)
        for hip, (a, _, _) in zip(hips, pairs, strict=True)
    ]
    comments["standing_pose"] = (
        f"solved by robot new: each four-bar's toe {STAND_SHARE:g} of its length under its "
        "motor axis, knees apart; solve: as deep under the hip at every design, the passive "
        "hinges solved per design to close the loops"
    )
    comments["loops"] = (
        "assumed: each leg's two halves turn about one axis and their ends meet at the "
        "model's zero pose: a four-bar whose pin the file leaves out (its simulator adds it "
        "in code); pinned at those ends, every hinge of a half after its first passive"
    )
    notes.append(
        f"four-bar legs ({len(pairs)}, each two chains whose ends meet): loops written, "
        f"their knees passive; the file's z taken as up; standing pose solved with each toe "
        f"{STAND_SHARE:g} of the leg's length under its motor axis"
    )
    pose = {"joints": joints, "solve": round(float(np.mean(shares)), 4)}
    return pose, hips, [legs[a] for a, _, _ in pairs]


def _first(model, leg: dict) -> str:
    return next(
        model.joint(j).name
        for b in leg["chain"]
        for j in range(model.njnt)
        if model.jnt_bodyid[j] == b and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
    )


def pair_names(first: list[str], second: list[str]) -> list[str]:
    """Each four-bar leg's name: the tokens its two halves' names share, in order (the
    first half's name where they share none or two legs would be named alike)."""
    out = []
    for a, b in zip(first, second, strict=True):
        shared = [t for t in a.split("_") if t in b.split("_")]
        out.append("_".join(shared) or a)
    return out if len(set(out)) == len(out) else first


def write_loops(data_out: dict, loops: list, pins: dict, comments: dict) -> None:
    """The spec's `loops` and `pins`, each where there are any."""
    if loops:
        data_out["loops"] = loops
    if pins:
        data_out["pins"] = pins
        comments["pins"] = (
            "assumed: where the other half's end meets this lower leg at the model's zero "
            "pose, short of its own end (its toe reaches on past the pin)"
        )
