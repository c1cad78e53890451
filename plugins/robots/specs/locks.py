"""Joints taken out of the robot (spec `locked_joints`, `model.prepare`) and the slide joints
`robot new` locks (`new`).

- `lock_joints(spec, names, at)`: each joint deleted from the model, its body then rigid on
  its parent: where the model draws it (the joint at its reference, 0 in a URDF), or at the
  value `at` gives (m for a slide: the body moved along the axis; rad for a hinge: the body
  turned about the axis through its anchor). The actuators that drive a locked joint go with
  it, and each keyframe loses the joint's and those actuators' entries, so it still loads.
- `slides_to_lock(model, base, key)`: the slide joints no actuator drives that sit between
  the base and a leg (on a leg's chain, above or on its first hinged body: PyBullet's
  minitaur_rainbow_dash_v1 hangs its motors on sprung brackets that its environment holds in
  code) and the value each is locked at: the keyframe's where the model has one, else the
  model's zero clipped into the joint's range.
"""

from __future__ import annotations

import mujoco
import numpy as np
from coadapt_plugins.robots.specs.fields import spec_error


def _drop(values, drop: set[int], size: int) -> list | None:
    """`values` without the entries at `drop`, when it holds `size` of them (else None:
    left as it is)."""
    values = list(values)
    if len(values) != size:
        return None
    return [v for k, v in enumerate(values) if k not in drop]


def _weld_at(joint: mujoco.MjsJoint, value: float, compiled: np.ndarray) -> None:
    """Move `joint`'s body as the joint at `value` would (module docstring); `compiled`
    the body's orientation as MuJoCo compiled it (where the model gives it as Euler angles,
    an axis-angle or axes, it becomes that quaternion)."""
    body = joint.parent
    quat = np.array(body.quat, dtype=float)
    if body.alt.type != mujoco.mjtOrientation.mjORIENTATION_QUAT:
        quat = np.array(compiled, dtype=float)
        body.alt.type = mujoco.mjtOrientation.mjORIENTATION_QUAT
    body.quat = quat
    shift = value - float(joint.ref)
    quat /= np.linalg.norm(quat)
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, quat)
    rot = rot.reshape(3, 3)
    axis = np.array(joint.axis, dtype=float)
    axis /= np.linalg.norm(axis)
    if joint.type == mujoco.mjtJoint.mjJNT_SLIDE:
        body.pos = np.array(body.pos, dtype=float) + rot @ (shift * axis)
        return
    turn = np.zeros(4)
    mujoco.mju_axisAngle2Quat(turn, axis, shift)
    turned = np.zeros(9)
    mujoco.mju_quat2Mat(turned, turn)
    anchor = np.array(joint.pos, dtype=float)
    body.pos = np.array(body.pos, dtype=float) + rot @ (anchor - turned.reshape(3, 3) @ anchor)
    out = np.zeros(4)
    mujoco.mju_mulQuat(out, quat, turn)
    body.quat = out


def lock_joints(spec: mujoco.MjSpec, names, at: dict | None = None) -> None:
    """Delete the joints `names` from `spec`, each body rigid where `at` says (module
    docstring); a name the model lacks is refused in one line."""
    at = at or {}
    names = list(names)
    if not names:
        return
    for name in names:
        if spec.joint(name) is None:
            raise spec_error("locked_joints", f"no joint '{name}' in the model")
    model = spec.compile()
    qpos = {a for n in names for a in _span(model, n, model.jnt_qposadr, model.nq)}
    qvel = {a for n in names for a in _span(model, n, model.jnt_dofadr, model.nv)}
    actuators = list(spec.actuators)  # the model's actuator order
    driven = [
        k
        for k, a in enumerate(actuators)
        if a.trntype == mujoco.mjtTrn.mjTRN_JOINT and a.target in names
    ]
    kept = [
        (key, attr, _drop(getattr(key, attr), drop, size))
        for key in spec.keys
        for attr, drop, size in (
            ("qpos", qpos, model.nq), ("qvel", qvel, model.nv), ("ctrl", set(driven), model.nu)
        )
    ]  # fmt: skip
    for k in driven:
        spec.delete(actuators[k])
    for name in names:
        joint = spec.joint(name)
        if name in at:
            _weld_at(joint, float(at[name]), model.body_quat[model.joint(name).bodyid[0]])
        spec.delete(joint)
    for key, attr, values in kept:  # after the deletions: MuJoCo checks each key's sizes
        if values is not None:
            setattr(key, attr, values)


def _span(model: mujoco.MjModel, name: str, adr, size: int) -> range:
    """The addresses (qpos or dof, by `adr`) of joint `name`."""
    j = model.joint(name).id
    later = [int(adr[k]) for k in range(model.njnt) if adr[k] > adr[j]]
    return range(int(adr[j]), min(later, default=size))


def slides_to_lock(model: mujoco.MjModel, base: int, key: int | None) -> dict[str, tuple]:
    """{slide joint: (the value it is locked at, its range or None, whether the zero was
    clipped into it)} for the slides between the base and the legs (module docstring);
    `key` the keyframe whose values are taken, None for the model's zero."""
    from coadapt_plugins.robots.specs.legs import _chain, _hinges

    driven = {
        int(model.actuator_trnid[a, 0])
        for a in range(model.nu)
        if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT
    }
    above: set[int] = set()  # bodies on a leg chain up to its first hinged body
    for leaf in range(1, model.nbody):
        if any(model.body_parentid[c] == leaf for c in range(1, model.nbody)):
            continue
        chain = _chain(model, base, leaf)
        if len(chain) < 2 or _hinges(model, chain) < 2:
            continue
        for b in chain:
            above.add(b)
            if _hinges(model, [b]):
                break
    out = {}
    for j in range(model.njnt):
        if model.jnt_type[j] != mujoco.mjtJoint.mjJNT_SLIDE or j in driven:
            continue
        if int(model.jnt_bodyid[j]) not in above:
            continue
        adr = int(model.jnt_qposadr[j])
        value = float(model.key_qpos[key, adr] if key is not None else model.qpos0[adr])
        span = tuple(float(x) for x in model.jnt_range[j]) if model.jnt_limited[j] else None
        clipped = False
        if key is None and span is not None and not span[0] <= value <= span[1]:
            value, clipped = float(np.clip(value, *span)), True
        out[model.joint(j).name] = (value, span, clipped)
    return out


def lock_slides(spec: mujoco.MjSpec, notes: list[str], comments: dict[str, str]) -> list:
    """Lock in `spec` the slides between the base and the legs (`slides_to_lock`, at the
    model's first "home" or "stand" keyframe, else its first, else its zero); returns their
    `locked_joints` entries (a name, or {name: value} where the body moves off where the
    model draws it) and says what it assumed in `notes` and `comments`."""
    from coadapt_plugins.robots.specs.legs import _base

    model = spec.compile()
    key = None
    if model.nkey:
        key = next((k for k in range(model.nkey) if model.key(k).name in ("home", "stand")), 0)
    found = slides_to_lock(model, _base(model), key)
    if not found:
        return []
    at = {
        name: value
        for name, (value, _, _) in found.items()
        if abs(value - float(model.qpos0[model.jnt_qposadr[model.joint(name).id]])) > 1e-12
    }
    lock_joints(spec, list(found), at)
    where = f"keyframe '{model.key(key).name or key}'" if key is not None else "0"
    said = []
    for name, (value, span, clipped) in found.items():
        text = f"{name} at {value:g} m"
        if clipped:
            text += f" (0 lies outside its range [{span[0]:g}, {span[1]:g}]: its nearest limit)"
        said.append(text)
    notes.append(
        f"slide joints between the base and the legs, locked (locked_joints): {'; '.join(said)}"
        " (a spec robot turns on hinges; the model's sprung or adjustable mounts held rigid)"
    )
    clipped = any(c for _, _, c in found.values())
    comments["locked_joints"] = (
        f"assumed: slide joints between the base and the legs held rigid at {where}"
        + (" (where 0 lies outside a joint's range: its nearest limit)" if clipped else "")
        + "; a spec robot turns on hinges"
    )
    return [{name: round(at[name], 9) + 0.0} if name in at else name for name in found]
