"""The standing pose `robot new` solves and the gains it raises (`new`): without a named
keyframe each foot goes under its hip at STAND_SHARE of its leg's length by the generic leg IK
(`kinematics`), and the gains, kp KP_PER_TORQUE per N m of peak torque, go up through
GAIN_FACTORS until the nominal design and every corner pass the stand test (`validation`); a
keyframe that stands at the nominal design but leaves a corner falling is solved again at each
design from its angles (`stand_by_gains`).
"""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np
from coadapt_plugins.robots.specs.assumed import spec_text
from coadapt_plugins.robots.specs.level import TILT
from coadapt_plugins.robots.specs.spec import SPEC_FILE

#: the stiffness written per N m of a joint's peak torque (the peak at 1 rad of error), and
#: the damping-to-stiffness ratio (legged_gym's A1 and Unitree's G1 settings: 0.02-0.025)
KP_PER_TORQUE = 1.0
KD_RATIO = 0.025
#: the factors `robot new` tries on those gains, in turn, until the nominal design stands
GAIN_FACTORS = (1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0)
#: a solved standing pose puts each foot under its hip at this share of the leg's length;
#: the IK starts with each leg's last hinge bent either way by BEND rad too
STAND_SHARE = 0.75
BEND = 0.6
#: a foot the model's pose holds out sideways by more than this share of its leg's length
#: (legs posed up or flat, `legs.ALIKE_COUNT`) cannot keep that offset 0.75 of the length
#: down: it is solved under its hip instead
OUT_SHARE = float(np.sqrt(1.0 - STAND_SHARE**2))


def _inside_ranges(model: mujoco.MjModel, data: mujoco.MjData, notes: list[str]) -> dict:
    """Joint angles for a pose: 0, or the nearest limit of a joint whose range excludes 0."""
    pose = {}
    for j in range(model.njnt):
        if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_HINGE or not model.jnt_limited[j]:
            continue
        lo, hi = (float(x) for x in model.jnt_range[j])
        if not lo <= 0.0 <= hi:
            angle = lo if abs(lo) < abs(hi) else hi
            pose[model.joint(j).name] = angle
            data.qpos[model.jnt_qposadr[j]] = angle
            notes.append(f"joint '{model.joint(j).name}': 0 is outside its range; {angle:g} rad")
    return pose


def _leg_length(model: mujoco.MjModel, leg: dict, params: list[dict]) -> float:
    """The leg's length: its design links' lengths summed (its chain's below the hip when
    it has none)."""
    names = {model.body(b).name for b in leg["chain"]}
    links = [c for p in params for parent, c in p["links"] if parent in names and c in names]
    bodies = [model.body(c).id for c in links] or leg["chain"][1:]
    return float(sum(np.linalg.norm(model.body_pos[b]) for b in bodies))


def _held_ankles(model: mujoco.MjModel, legs: list[dict]) -> frozenset:
    """The hinges of each foot body after its first: an ankle of stacked hinges turns about
    its first in the standing solve, the others stay at their reference."""
    return frozenset(
        model.joint(j).name
        for g in legs
        for j in [
            j
            for j in range(model.njnt)
            if model.jnt_bodyid[j] == g["foot"] and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
        ][1:]
    )


def _starts(model, joints, legs, guess, ranges, held) -> list[np.ndarray]:
    """The IK's three starts: the guess, and each leg's last hinge (not held) bent either
    way by BEND inside its range."""
    starts = []
    for bend in (0.0, BEND, -BEND):
        start = guess.copy()
        for g in legs:
            hinges = [
                joints.index(model.joint(j).name)
                for j in range(model.njnt)
                if model.jnt_bodyid[j] in g["chain"]
                and model.joint(j).name in joints
                and model.joint(j).name not in held
            ]
            if hinges and bend:
                k = hinges[-1]
                lo, hi = ranges[joints[k]]
                start[k] = float(np.clip(start[k] + bend, lo, hi))
        starts.append(start)
    return starts


def _knee_starts(model, joints, legs, guess, ranges, held, params) -> list[np.ndarray]:
    """Two more starts for legs the first three left unplaced: each leg's knee (its last
    hinge, not held, a quarter of the leg's length or more above the foot along the chain)
    bent either way by BEND. A straight leg is the IK's singular point, which bending an
    ankle (the last hinge of a leg with one) does not leave."""
    starts = []
    for bend in (BEND, -BEND):
        start = guess.copy()
        for g in legs:
            chain = list(g["chain"])
            length = _leg_length(model, g, params)
            for j in reversed(range(model.njnt)):
                body = int(model.jnt_bodyid[j])
                name = model.joint(j).name
                if body not in chain or name not in joints or name in held:
                    continue
                below = chain[chain.index(body) + 1 :]
                if sum(float(np.linalg.norm(model.body_pos[b])) for b in below) >= 0.25 * length:
                    k = joints.index(name)
                    start[k] = float(np.clip(start[k] + bend, *ranges[name]))
                    break
        starts.append(start)
    return starts


def _knee(slot, anchors, foot, length: float) -> int:
    """The element of a leg's knee: its last hinge whose anchor lies a quarter of the leg's
    length from the foot or more (an ankle's hinges lie nearer)."""
    turning = torch_nonzero(slot)
    far = [e for e in turning if float((anchors[e] - foot).norm()) >= 0.25 * length]
    return far[-1] if far else turning[-1]


def torch_nonzero(slot) -> list[int]:
    return [e for e, s in enumerate(slot.tolist()) if s >= 0]


def _candidate(kin, q, k, fit, model, leg, params, quadruped_like, init):
    """(score, angles, slots) of leg k in the IK's answer q, or None when a joint lies
    outside its range, the foot misses its target by 2 % of the leg's length or more, or
    (an answer iterated from a bent knee, `init`) the sole turned more than TILT."""
    import torch

    designs, targets, upright, lo, hi = fit
    chain = kin.chain
    foot, turned, hip, _, anchors = kin.forward(
        kin.scales(designs), kin.leg_angles(torch.tensor(q[None, :]))
    )
    slots = chain.joint_index[k][chain.joint_index[k] >= 0].numpy()
    inside = bool(np.all((q[slots] >= lo[slots] - 1e-9) & (q[slots] <= hi[slots] + 1e-9)))
    error = float(torch.linalg.norm(foot[0, k] - hip[0, k] - targets[0, k]))
    length = _leg_length(model, leg, params)
    if not inside or error > 0.02 * length:
        return None
    cos = 0.5 * (float(torch.trace(turned[0, k].T @ upright[0, k])) - 1.0)
    tilt = float(np.arccos(np.clip(cos, -1.0, 1.0)))
    if init is not None and tilt > TILT:  # a bent knee's answer must keep the sole
        return None
    knee = _knee(chain.slot[k], anchors[0, k], foot[0, k], length)
    knee_x = float(anchors[0, k, knee, 0] - 0.5 * (foot[0, k, 0] + hip[0, k, 0]))
    behind = knee_x < 0 if quadruped_like else knee_x > 0
    score = error + (0.0 if behind else 0.01 * length)
    if len(slots) > 3:  # a leg with an ankle: its foot as it stands (flat) first
        score += 0.01 * length * tilt
    return score, q[slots].copy(), slots


def _solve_standing(
    model: mujoco.MjModel,
    base: int,
    joints: list[str],
    legs: list[dict],
    params: list[dict],
    guess: np.ndarray,
    ranges: dict[str, tuple[float, float]],
    quadruped_like: bool,
    hips: list[str | None] | None = None,
) -> tuple[np.ndarray, list[str]]:
    """A standing pose with each foot under its hip at STAND_SHARE of its leg's length, by
    the generic leg IK from three starts (the guess, and its last hinge per leg bent either
    way; a leg none of these places gets two more, its knee bent either way, whose answer
    must keep the sole: `_knee_starts`); per leg the start whose answer is inside the joint
    ranges and nearest its target, a quadruped's knee behind its hip-foot line and a biped's
    in front on a tie. Returns the
    pose and the legs (by index) it could not place, which keep the guess. `hips`: each
    leg's hip body (None: the first below the base), as the spec's legs name them."""
    import torch
    from coadapt_plugins.robots.specs.kinematics import LegKinematics, build_chain

    links = [set(map(tuple, p["links"])) for p in params]
    nominal = np.ones(len(params))
    held = _held_ankles(model, legs)
    hips = hips or [None] * len(legs)
    feet = [(model.body(g["foot"]).name, hip) for g, hip in zip(legs, hips, strict=True)]
    starts = _starts(model, joints, legs, guess, ranges, held)
    designs = torch.tensor(nominal[None, :])
    try:
        first = LegKinematics(
            build_chain(
                model, model.body(base).name, joints, feet, links, starts[0], nominal, held=held
            )
        )
    except ValueError:  # legs that share a joint (a humanoid's abdomen): no leg IK for them
        return guess.copy(), list(range(len(legs)))
    rel, upright, _ = first.standing(designs)
    targets = torch.zeros_like(rel)
    for k, g in enumerate(legs):
        side = float(rel[0, k, 1])
        if g.get("raised") and abs(side) > OUT_SHARE * _leg_length(model, g, params):
            side, g["under"] = 0.0, True  # posed out sideways, beyond reach: under its hip
        targets[0, k, 1] = side
        targets[0, k, 2] = -STAND_SHARE * _leg_length(model, g, params)
    best: list[tuple[float, np.ndarray] | None] = [None] * len(legs)
    pose = guess.copy()
    lo = np.array([ranges[j][0] for j in joints])
    hi = np.array([ranges[j][1] for j in joints])

    def attempt(start: np.ndarray, legs_open: list[int], init=None) -> None:
        kin = LegKinematics(
            build_chain(
                model, model.body(base).name, joints, feet, links, start, nominal, held=held
            )
        )
        q = kin.inverse(designs, targets, init)[0].numpy()
        fit = (designs, targets, upright, lo, hi)
        for k in legs_open:
            found = _candidate(kin, q, k, fit, model, legs[k], params, quadruped_like, init)
            if found is not None and (best[k] is None or found[0] < best[k][0]):
                best[k] = found

    for start in starts:
        attempt(start, list(range(len(legs))))
    open_legs = [k for k, found in enumerate(best) if found is None]
    if open_legs:  # straight legs whose last hinge is an ankle: bend their knees instead
        for start in _knee_starts(model, joints, legs, guess, ranges, held, params):
            # iterated from the bent knee, the soles kept as they are at the guess
            attempt(starts[0], open_legs, torch.tensor(start))
    missed = []
    for k, found in enumerate(best):
        if found is None:
            missed.append(k)
            continue
        pose[found[2]] = found[1]
    return pose, missed


def _pose_entry(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    key: int,
    base: int,
    joints: list[str],
    legs: list[dict],
    params: list[dict],
    ranges: dict[str, tuple[float, float]],
    notes: list[str],
    comments: dict[str, str],
) -> tuple[dict, list[str] | None]:
    """(The spec's `standing_pose`, each leg's `hip` where it is not the first body below
    the base, else None). The standing pose: the model's first "home" or "stand" keyframe (else its
    first) when it has a name, else the pose `_solve_standing` finds from `data`'s, solved
    again at each design (`solve`) when it placed every foot."""
    hips = None
    if model.nkey and model.key(key).name:
        pose: dict = {"keyframe": model.key(key).name}
    else:
        if model.nkey:
            notes.append("the first keyframe has no name: it is not used")
        guess = np.array([data.qpos[model.jnt_qposadr[model.joint(j).id]] for j in joints])
        guess = np.clip(guess, [ranges[j][0] for j in joints], [ranges[j][1] for j in joints])
        solved, missed = _solve_standing(
            model, base, joints, legs, params, guess, ranges, len(legs) >= 4
        )
        hinged = _hinged_hips(model, legs)
        if hinged:  # measured from the first body that turns (below a locked waist)
            again, left = _solve_standing(
                model, base, joints, legs, params, guess, ranges, len(legs) >= 4, hinged
            )
            if len(left) <= len(missed) and len(left) < len(legs):
                solved, missed, hips = again, left, hinged
                comments["legs"] = (
                    "hip: the first body of each leg that turns (the body below the base does not)"
                )
        if any(g.get("under") for k, g in enumerate(legs) if k not in missed):
            notes.append(
                f"the model's pose holds its legs up or flat, the feet out sideways beyond "
                f"reach (no two feet below its base): its {len(legs)} alike chains of "
                f"{_hinge_count(model, legs[0])} hinges taken as the legs, each foot solved "
                "under its hip"
            )
        pose = {
            "joints": {
                j: round(float(v), 6) for j, v in zip(joints, solved, strict=True) if abs(v) > 1e-12
            }
        }
        if not missed:  # every foot placed: solved again at each design from this pose
            pose["solve"] = STAND_SHARE
        placed = len(legs) - len(missed)
        comments["standing_pose"] = (
            f"solved by robot new: feet {STAND_SHARE:g} of the leg's length under their hips "
            "(generic leg IK)"
            + ("; solve: solved so at every design" if not missed else "")
            + (f"; {len(missed)} legs out of reach keep 0 or their nearest limit" if missed else "")
        )
        notes.append(
            f"no keyframe: standing pose solved with {placed} of {len(legs)} feet "
            f"{STAND_SHARE:g} of the leg's length under their hips"
            + ("" if not missed else "; the others at 0 or their nearest limit")
        )
    return pose, hips


def _hinge_count(model: mujoco.MjModel, leg: dict) -> int:
    from coadapt_plugins.robots.specs.legs import _hinges

    return _hinges(model, leg["chain"])


def _hinged_hips(model: mujoco.MjModel, legs: list[dict]) -> list[str] | None:
    """Each leg's first body holding a hinge, where one differs from the first body below
    the base (a humanoid's waist, its joints locked), else None."""
    hips = []
    for g in legs:
        turning = [
            b
            for b in g["chain"]
            if any(
                model.jnt_bodyid[j] == b and model.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE
                for j in range(model.njnt)
            )
        ]
        hips.append(model.body(turning[0] if turning else g["chain"][0]).name)
    if all(h == model.body(g["chain"][0]).name for h, g in zip(hips, legs, strict=True)):
        return None
    return hips


def _set_gains(data: dict, factor: float) -> None:
    for row, peak in zip(data["gains"].values(), data["limits"]["torque"].values(), strict=True):
        row["kp"] = round(factor * KP_PER_TORQUE * peak, 6)
        row["kd"] = round(factor * KD_RATIO * KP_PER_TORQUE * peak, 6)


def _raise_gains(folder: Path, data: dict, comments: dict):
    """(the first factor of GAIN_FACTORS at which the nominal design and every corner pass
    the stand test, else the last; the stand test that decided; the first factor at which
    the nominal design alone passed, or None; the stand test that decided at that factor)."""
    from coadapt_plugins.robots.specs.robot import spec_robot_class
    from coadapt_plugins.robots.specs.validation import corners, stand_test

    nominal_ok, at_nominal_ok = None, None
    for factor in GAIN_FACTORS:
        _set_gains(data, factor)
        (folder / SPEC_FILE).write_text(spec_text(data, comments), encoding="utf-8")
        robot = spec_robot_class(folder)()
        stand = stand_test(robot.build(_nominal(data)))  # it must build
        if stand.ok:
            stand = next(
                (t for t in (stand_test(robot.build(c)) for c in corners(robot)) if not t.ok),
                stand,
            )
            if nominal_ok is None:
                nominal_ok, at_nominal_ok = factor, stand
        if stand.ok:
            return factor, stand, nominal_ok, at_nominal_ok
    return factor, stand, nominal_ok, at_nominal_ok


def _nominal(data: dict) -> np.ndarray:
    return np.array([p["nominal"] for p in data["design"]], dtype=float)


def _keyframe_solved(folder: Path, data: dict, comments: dict) -> dict | None:
    """The spec's keyframe pose as `{joints, solve}`: its joint angles the nominal pose and,
    as the share, its own feet's mean depth under their hips over the leg's length, so the
    nominal design keeps about the keyframe's pose and every design puts its feet under its
    hips as deep. None when the leg IK cannot take it."""
    import torch
    from coadapt_plugins.robots.specs.robot import spec_robot_class

    from coadapt_core.errors import UserError

    built = spec_robot_class(folder)()._built
    joints = {
        j: round(float(v), 6)
        for j, v in zip(built.prepared.joints, built.prepared.standing, strict=True)
        if abs(v) > 1e-12
    }
    trial = {**data, "standing_pose": {"joints": joints, "solve": 0.5}}
    (folder / SPEC_FILE).write_text(spec_text(trial, comments), encoding="utf-8")
    nominal = torch.as_tensor(_nominal(data)[None])
    try:
        built = spec_robot_class(folder)()._built
        half = built.stand_targets(nominal, level=False)[0, :, 2]  # -0.5 x each leg's length
        depth = built.kinematics.standing(nominal)[0][0, :, 2]  # the keyframe's feet
    except (UserError, ValueError):
        return None
    share = round(float((depth / (2.0 * half)).mean()), 4)
    return {"joints": joints, "solve": share} if 0.0 < share < 1.0 else None


def stand_by_gains(folder: Path, data: dict, comments: dict, notes: list[str]):
    """`_raise_gains`; and when a keyframe's pose stands at the nominal design but not at a
    corner (a leg's segments scaled apart move its foot out from under its hip), the same
    pose solved again at each design (`_keyframe_solved`), kept when then every corner
    stands. Returns `_raise_gains`'s four values."""
    first = _raise_gains(folder, data, comments)
    pose = data["standing_pose"]
    if first[1].ok or first[2] is None or "keyframe" not in pose:
        return first
    solved = _keyframe_solved(folder, data, comments)
    if solved is not None:
        data["standing_pose"] = solved
        second = _raise_gains(folder, data, comments)
        if second[1].ok:
            comments["standing_pose"] = (
                f"keyframe '{pose['keyframe']}', solved at each design with the feet "
                f"{solved['solve']:g} of the leg's length under their hips (robot new: the "
                "keyframe alone leaves a corner falling under joint PD)"
            )
            notes.append(
                f"keyframe '{pose['keyframe']}' solved at each design (solve: "
                f"{solved['solve']:g}): with its angles at every design a corner falls under "
                "joint PD"
            )
            return second
    data["standing_pose"] = pose
    return _raise_gains(folder, data, comments)
