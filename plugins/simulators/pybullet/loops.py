"""A robot's closed loops in PyBullet: a URDF is a tree, so a loop the robot's MJCF closes
(a `<connect>` between two bodies: a four-bar leg's pin) is read from the compiled MJCF
(`mjcf_loops`, as the joint dynamics are) and added once the URDF is loaded, as PyBullet's
own minitaur environment closes its legs: a point-to-point constraint between the two
links (`add_loops`). The movable joints no motor drives (the loop's passive hinges) lose
the velocity motor Bullet gives every joint by default.
"""

from __future__ import annotations

import numpy as np
import pybullet as p

#: the largest force (N) a loop's point-to-point constraint applies
LOOP_FORCE = 1.0e6


def mjcf_loops(mj) -> list[tuple[str, tuple, str, tuple]]:
    """(body A, point in A's frame, body B, point in B's frame) per `<connect>` of the
    compiled MJCF model `mj`, written with two sites or with two bodies and an anchor."""
    import mujoco

    out = []
    for e in range(mj.neq):
        if mj.eq_type[e] != mujoco.mjtEq.mjEQ_CONNECT:
            continue
        a, b = int(mj.eq_obj1id[e]), int(mj.eq_obj2id[e])
        if mj.eq_objtype[e] == mujoco.mjtObj.mjOBJ_SITE:
            ends = [(int(mj.site_bodyid[s]), mj.site_pos[s]) for s in (a, b)]
        else:  # body1's anchor, and body2's where it was at qpos0 (MuJoCo computes it)
            ends = [(a, mj.eq_data[e, 0:3]), (b, mj.eq_data[e, 3:6])]
        (ba, pa), (bb, pb) = ends
        out.append(
            (mj.body(ba).name, tuple(map(float, pa)), mj.body(bb).name, tuple(map(float, pb)))
        )
    return out


def _in_com_frame(client: int, body: int, link: int, point) -> list[float]:
    """A point in a link's URDF frame, in the frame Bullet's constraints use (its centre of
    mass's)."""
    info = p.getDynamicsInfo(body, link, physicsClientId=client)
    rot = np.array(p.getMatrixFromQuaternion(info[4])).reshape(3, 3)
    return [float(x) for x in rot.T @ (np.asarray(point, dtype=float) - np.asarray(info[3]))]


def add_loops(client: int, body: int, names: dict, loops, actuated: list[int]) -> None:
    """The loops' point-to-point constraints on a loaded `body` (`names`: "link:NAME" ->
    link index), and no default motor on a movable joint outside `actuated`."""
    if not loops:
        return
    for a, pa, b, pb in loops:
        la, lb = names["link:" + a], names["link:" + b]
        c = p.createConstraint(
            body, la, body, lb, p.JOINT_POINT2POINT, [0.0, 0.0, 0.0],
            _in_com_frame(client, body, la, pa), _in_com_frame(client, body, lb, pb),
            physicsClientId=client,
        )  # fmt: skip
        p.changeConstraint(c, maxForce=LOOP_FORCE, physicsClientId=client)
    free = [
        i
        for i in range(p.getNumJoints(body, physicsClientId=client))
        if i not in actuated and p.getJointInfo(body, i, physicsClientId=client)[2] != p.JOINT_FIXED
    ]
    p.setJointMotorControlArray(
        body, free, p.VELOCITY_CONTROL, targetVelocities=[0.0] * len(free),
        forces=[0.0] * len(free), physicsClientId=client,
    )  # fmt: skip
