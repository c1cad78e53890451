"""URDF rewrites the PyBullet backend needs before loading a design.

- Base centre-of-mass shift (domain randomization): PyBullet's `changeDynamics` cannot move
  a link's inertial frame, so the shift is written into the base link's `<inertial><origin>`
  and the body is reloaded.
- Joint armature (MuJoCo's reflected rotor inertia): PyBullet has no armature. It is added
  to the child link's rotational inertia about the joint axis, which gives each joint the
  same extra inertia about its own axis (the diagonal term MuJoCo adds); see
  docs/sim-to-sim.md for what this approximation leaves out.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np


def _floats(text: str | None, n: int, default: float = 0.0) -> np.ndarray:
    if not text:
        return np.full(n, default)
    return np.array([float(v) for v in text.split()])


def _rpy_matrix(rpy: np.ndarray) -> np.ndarray:
    """URDF fixed-axis roll-pitch-yaw: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def _fmt(values: np.ndarray) -> str:
    return " ".join(f"{v:.12g}" for v in values)


def _inertial(link: ET.Element) -> ET.Element:
    inertial = link.find("inertial")
    if inertial is None:
        raise ValueError(f"URDF link '{link.get('name')}' has no <inertial>")
    return inertial


def _physical(inertia: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Make a tensor that gained armature about `axis` satisfy the triangle inequality of
    principal moments again (PyBullet zeroes an inertia that violates it), adding the least
    inertia about the two directions perpendicular to the axis."""
    perpendicular = np.eye(3) - np.outer(axis, axis)
    for _ in range(8):
        moments = np.linalg.eigvalsh(inertia)
        excess = moments[2] - moments[0] - moments[1]
        if excess <= 0:
            return inertia
        inertia = inertia + (excess / 2 + 1e-9) * perpendicular
    return inertia


def prepare_urdf(
    urdf: str,
    base_body: str,
    com_shift: np.ndarray | None = None,  # [3] m, in the base link frame
    armature: dict[str, float] | None = None,  # joint name -> kg m^2
) -> str:
    """The URDF text with the base CoM shifted and armature folded into link inertias."""
    root = ET.fromstring(urdf)
    links = {link.get("name"): link for link in root.findall("link")}
    if com_shift is not None and np.any(com_shift != 0):
        inertial = _inertial(links[base_body])
        origin = inertial.find("origin")
        if origin is None:
            origin = ET.SubElement(inertial, "origin")
        xyz = _floats(origin.get("xyz"), 3) + np.asarray(com_shift, dtype=float)
        origin.set("xyz", _fmt(xyz))
    for joint in root.findall("joint"):
        a = (armature or {}).get(joint.get("name"), 0.0)
        if a <= 0:
            continue
        axis_el = joint.find("axis")
        axis = _floats(axis_el.get("xyz") if axis_el is not None else None, 3, 0.0)
        if not np.any(axis):
            axis = np.array([1.0, 0.0, 0.0])  # URDF default axis
        axis = axis / np.linalg.norm(axis)
        child = links[joint.find("child").get("link")]
        inertial = _inertial(child)
        origin = inertial.find("origin")
        rpy = _floats(origin.get("rpy") if origin is not None else None, 3)
        # the joint axis is given in the child link frame; the inertia tensor in the
        # inertial frame, rotated by rpy from the link frame
        axis_inertial = _rpy_matrix(rpy).T @ axis
        tensor = inertial.find("inertia")
        keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
        v = {k: float(tensor.get(k, 0.0)) for k in keys}
        inertia = np.array(
            [
                [v["ixx"], v["ixy"], v["ixz"]],
                [v["ixy"], v["iyy"], v["iyz"]],
                [v["ixz"], v["iyz"], v["izz"]],
            ]
        )
        inertia = _physical(inertia + a * np.outer(axis_inertial, axis_inertial), axis_inertial)
        for k, (i, j) in zip(keys, [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)], strict=True):
            tensor.set(k, f"{inertia[i, j]:.12g}")
    return ET.tostring(root, encoding="unicode")
