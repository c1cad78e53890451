"""A spec robot's left-right mirror map (`Robot.mirror`, which `TrainConfig.symmetry` uses),
derived from the spec and its model, nothing written by hand:

- legs pair by name: a leg's side tokens swapped (left <-> right, l <-> r, FL <-> FR,
  RL <-> RR, HL <-> HR, ...) name its mirror leg; a name without one is its own mirror;
- the actuated joints of a leg's chain (base to foot, in order) pair with those of its
  mirror leg; a joint on no leg is its own mirror;
- each pair is checked on the model at the nominal design and zero joint angles: the
  anchors must be mirror images through the base's x-z plane and the axes parallel to the
  mirrored axis (either way); the sign is -(axis' . mirrored axis): +1 for pitch joints
  with the same axis on both sides, -1 for roll and yaw joints. The standing pose must be
  its own mirror image within `POSE_TOL`;
- a design parameter's links (a motor parameter's joints) on some legs pair it with the
  parameter on the mirror legs (itself when those are the same legs).

Anything that does not pair or check is one line saying what, and the robot has no map.
"""

from __future__ import annotations

import re

import mujoco
import numpy as np
from coadapt_plugins.robots.specs.legs import _chain
from coadapt_plugins.robots.specs.spec import match_value

from coadapt_core.errors import UserError
from coadapt_core.robot import Mirror

_PAIRS = {"left": "right", "l": "r", "fl": "fr", "rl": "rr", "hl": "hr", "ml": "mr", "bl": "br"}
_PAIRS.update({"lf": "rf", "lh": "rh", "lm": "rm", "lr": "rr", "lb": "rb"})
SIDES = {**_PAIRS, **{v: k for k, v in _PAIRS.items()}}
#: metres: how far a joint's anchor may lie from its partner's mirror image
ANCHOR_TOL = 1e-4
#: how far |cos| between an axis and its partner's mirrored axis may fall short of 1
AXIS_TOL = 1e-4
#: rad: how far a joint's standing angle may lie from its partner's mirrored angle (a file's
#: rounded rotations, `rpy` 1.57075 for pi/2, move a solved pose by 1e-4 rad; a link 1 mm
#: longer on one side, by 1e-2)
POSE_TOL = 1e-3


def mirrored_name(name: str) -> str:
    """`name` with every side token swapped, the case kept ("FL_foot" -> "FR_foot")."""

    def swap(match: re.Match) -> str:
        token = match.group(0)
        other = SIDES.get(token.lower())
        if other is None:
            return token
        if token.isupper():
            return other.upper()
        return other.capitalize() if token[0].isupper() else other

    return re.sub(r"[A-Za-z]+", swap, name)


def _fail(robot, why: str) -> UserError:
    return UserError(
        f"symmetry: robot '{robot.name}' has no left-right mirror map: {why}", field="symmetry"
    )


def _leg_map(robot) -> list[int]:
    names = [leg.name for leg in robot.spec.legs]
    out = []
    for name in names:
        other = mirrored_name(name)
        if other not in names:
            raise _fail(robot, f"leg '{name}' has no mirror leg named '{other}'")
        out.append(names.index(other))
    return out


def _chains(robot, model: mujoco.MjModel, base: int, joints: list[str]) -> list[list[int]]:
    """Each leg's actuated joints, base to foot (indices into `joints`); a leg closed by
    `loops` (a four-bar) holds its other halves' motors too, the leg's motors ordered from
    the base's x-z plane outward (side by side on one axis: the mirror pairs outer with
    outer)."""
    from coadapt_plugins.robots.specs.loops import loop_leg

    index = {model.joint(name).id: k for k, name in enumerate(joints)}
    feet = [leg.foot for leg in robot.spec.legs]
    chains = []
    for number, leg in enumerate(robot.spec.legs):
        ends = [leg.foot] + [
            b for a, b, _ in robot.spec.loops if loop_leg(model, base, feet, a) == number
        ]
        bodies = [b for end in ends for b in _chain(model, base, model.body(end).id)]
        found = [
            index.get(j) for b in bodies for j in range(model.njnt) if model.jnt_bodyid[j] == b
        ]
        found = [k for k in found if k is not None]  # locked joints are not actuated
        if len(ends) > 1:
            data = mujoco.MjData(model)
            mujoco.mj_kinematics(model, data)
            side = data.xmat[base].reshape(3, 3)[:, 1]
            found.sort(
                key=lambda k: round(
                    abs(float((data.xanchor[model.joint(joints[k]).id] - data.xpos[base]) @ side)),
                    4,
                )
            )
        chains.append(found)
    return chains


def _joint_map(robot, chains: list[list[int]], legs: list[int], count: int) -> list[int]:
    joints = robot._built.prepared.joints
    out: list[int | None] = [None] * count
    for leg, chain in enumerate(chains):
        other = chains[legs[leg]]
        if len(other) != len(chain):
            names = [robot.spec.legs[k].name for k in (leg, legs[leg])]
            raise _fail(robot, f"legs {names} have {len(chain)} and {len(other)} joints")
        for a, b in zip(chain, other, strict=True):
            if out[a] not in (None, b):
                raise _fail(robot, f"joint '{joints[a]}' pairs with two joints")
            out[a] = b
    return [k if m is None else m for k, m in enumerate(out)]


def _signs(robot, model, data, base: int, pairs: list[int]) -> list[float]:
    """Each joint's sign in the mirror image, checking the pairs' anchors and axes."""
    joints = robot._built.prepared.joints
    rot, origin = data.xmat[base].reshape(3, 3), data.xpos[base]
    flip = np.array([1.0, -1.0, 1.0])
    signs = []
    for k, m in enumerate(pairs):
        a, b = model.joint(joints[k]).id, model.joint(joints[m]).id
        gap = np.linalg.norm(
            rot.T @ (data.xanchor[a] - origin) - flip * (rot.T @ (data.xanchor[b] - origin))
        )
        if gap > ANCHOR_TOL:
            raise _fail(
                robot,
                f"joints '{joints[k]}' and '{joints[m]}' are not mirror images "
                f"(anchors {gap:.2g} m apart after mirroring)",
            )
        cos = float(rot.T @ data.xaxis[a] @ (flip * (rot.T @ data.xaxis[b])))
        if abs(abs(cos) - 1.0) > AXIS_TOL:
            raise _fail(robot, f"the axes of '{joints[k]}' and '{joints[m]}' are not mirrored")
        signs.append(-1.0 if cos > 0 else 1.0)
    return signs


def _design_map(robot, legs: list[int], pairs: list[int], model) -> dict[str, str]:
    """Design variables that trade places in the mirror image (both directions)."""
    spec, joints = robot.spec, robot._built.prepared.joints
    leg_bodies = [
        {model.body(b).name for b in _chain(model, model.body(robot._built.prepared.base).id, f)}
        for f in (model.body(leg.foot).id for leg in spec.legs)
    ]
    groups: list[tuple[str, frozenset, frozenset, tuple]] = []
    for p in spec.parameters:
        on = frozenset(k for k, bodies in enumerate(leg_bodies) for _, c in p.links if c in bodies)
        groups.append((p.name, on, frozenset(legs[k] for k in on), (p.low, p.high, p.nominal)))
    for p in spec.motor_parameters:
        on = frozenset(
            k for k, j in enumerate(joints) if any(match_value({q: 1}, j) for q in p.joints)
        )
        groups.append((p.name, on, frozenset(pairs[k] for k in on), ("motor", p.nominal)))
    out = {}
    for name, on, image, kind in groups:
        if image == on:
            continue
        match = [g[0] for g in groups if g[1] == image and g[3] == kind]
        if not match:
            raise _fail(robot, f"design variable '{name}' has no mirror variable")
        out[name] = match[0]
    return out


def derive_mirror(robot) -> Mirror:
    """The mirror map of a spec robot (module docstring), or a one-line `UserError`."""
    built = robot._built
    joints = built.prepared.joints
    nominal = robot.nominal_design(False)
    model = built.edited(nominal)[0].compile()
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)  # zero joint angles
    base = model.body(built.prepared.base).id
    legs = _leg_map(robot)
    chains = _chains(robot, model, base, joints)
    pairs = _joint_map(robot, chains, legs, len(joints))
    signs = _signs(robot, model, data, base, pairs)
    pose = robot.build(nominal).default_joint_pos
    for k, m in enumerate(pairs):
        if abs(pose[k] - signs[k] * pose[m]) > POSE_TOL:
            raise _fail(
                robot,
                f"the standing pose is not its own mirror image ('{joints[k]}' {pose[k]:.4g}, "
                f"'{joints[m]}' {pose[m]:.4g} rad)",
            )
    designs = _design_map(robot, legs, pairs, model)
    return Mirror(tuple(pairs), tuple(signs), tuple(legs), designs)
