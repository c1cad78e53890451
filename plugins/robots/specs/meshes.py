"""The mesh geoms of a spec's scaled links (`model`): when the model loads, each mesh geom of
a scaled body gets a mesh of its own (the compiled vertices, in the geom's compiled frame) for
a design to stretch; a collision mesh that cannot stretch (no principal axis within 8 deg of
the link) is refused in one line, or with spec `collision: fit` replaced by the primitive
MuJoCo fits to it that is closest to it in volume.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
from coadapt_plugins.robots.specs.spec import RobotSpec, spec_error

#: a geom lies along a link when its axis is within this angle of it (cosine)
ALONG = math.cos(math.radians(8.0))


def _quat_mat(q) -> np.ndarray:
    m = np.zeros(9)
    mujoco.mju_quat2Mat(m, np.asarray(q, dtype=float))
    return m.reshape(3, 3)


_MESH = mujoco.mjtGeom.mjGEOM_MESH
#: the primitives `collision: fit` chooses from (an ellipsoid has no URDF shape)
_FITS = {
    mujoco.mjtGeom.mjGEOM_BOX: "box",
    mujoco.mjtGeom.mjGEOM_CAPSULE: "capsule",
    mujoco.mjtGeom.mjGEOM_CYLINDER: "cylinder",
}


def _scaled_links(spec: mujoco.MjSpec, rs: RobotSpec) -> dict[str, list[tuple[np.ndarray, str]]]:
    """Body name -> (unit vector, spec field) of each scaled link it is the parent of."""
    out: dict[str, list[tuple[np.ndarray, str]]] = {}
    for k, p in enumerate(rs.parameters):
        for m, (parent, child) in enumerate(p.links):
            body, kid = spec.body(parent), spec.body(child)
            if body is None or kid is None or kid.parent.name != parent:
                continue  # `check_names` says what is wrong
            vector = np.array(kid.pos, dtype=float)
            if np.linalg.norm(vector) >= 1e-9:
                out.setdefault(parent, []).append(
                    (vector / np.linalg.norm(vector), f"design[{k}].links[{m}]")
                )
    return out


def _collides(geom: mujoco.MjsGeom) -> bool:
    return bool(geom.contype or geom.conaffinity)


def _set_frame(geom: mujoco.MjsGeom, pos, quat) -> None:
    geom.pos = np.array(pos, dtype=float)
    geom.quat = np.array(quat, dtype=float)
    geom.alt.type = mujoco.mjtOrientation.mjORIENTATION_QUAT


def off_link_degrees(model: mujoco.MjModel, g: int, u: np.ndarray) -> float:
    """How far (deg) the link direction `u` (body frame) lies from the nearest principal axis
    of mesh geom g (its compiled frame); a collision mesh within 8 deg stretches."""
    axes = _quat_mat(model.geom_quat[g])
    return math.degrees(math.acos(min(1.0, float(np.abs(axes.T @ u).max()))))


def _own_meshes(spec: mujoco.MjSpec, model: mujoco.MjModel, rs: RobotSpec) -> list[str]:
    """Give each mesh geom of a scaled body a mesh of its own in its compiled frame, fit or
    refuse the collision meshes that cannot stretch (module docstring); the fit's lines."""
    to_fit, replaced = [], set()
    for name, links in _scaled_links(spec, rs).items():
        body, b = spec.body(name), model.body(name).id
        for k, geom in enumerate(body.geoms):
            g = int(model.body_geomadr[b]) + k
            if geom.type != _MESH:
                if geom.meshname:  # a primitive MuJoCo fits to a mesh: keep the fit, stretch it
                    geom.size = model.geom_size[g]
                    _set_frame(geom, model.geom_pos[g], model.geom_quat[g])
                    geom.meshname = ""
                continue
            label = f"'{geom.name}'" if geom.name else f"number {k}"
            if _collides(geom):
                if rs.collision == "fit":
                    to_fit.append((name, k, g, label))
                    continue
                for u, where in links:
                    off = off_link_degrees(model, g, u)
                    if off > math.degrees(math.acos(ALONG)):
                        raise spec_error(
                            where,
                            f"the collision mesh {label} of body '{name}' lies {off:.0f} deg off "
                            "the link, so it cannot stretch along it: write `collision: fit` in "
                            "the spec to replace it by a fitted primitive, or make it visual "
                            "(contype=0 conaffinity=0)",
                        )
            replaced.add(geom.meshname)
            mid = int(model.geom_dataid[g])
            v0, nv = model.mesh_vertadr[mid], model.mesh_vertnum[mid]
            f0, nf = model.mesh_faceadr[mid], model.mesh_facenum[mid]
            source = spec.mesh(geom.meshname)
            mesh = spec.add_mesh(name=f"coadapt_stretch_{g}")
            mesh.uservert = model.mesh_vert[v0 : v0 + nv].ravel()
            mesh.userface = model.mesh_face[f0 : f0 + nf].ravel()
            mesh.inertia = source.inertia
            mesh.maxhullvert = source.maxhullvert
            geom.meshname = mesh.name
            _set_frame(geom, model.geom_pos[g], model.geom_quat[g])
    lines = _fit(spec, model, to_fit, replaced) if to_fit else []
    used = {geom.meshname for geom in spec.geoms}
    for name in replaced - used:
        spec.delete(spec.mesh(name))
    return lines


def _mesh_volume(model: mujoco.MjModel, g: int) -> float:
    mid = int(model.geom_dataid[g])
    v0, f0, nf = model.mesh_vertadr[mid], model.mesh_faceadr[mid], model.mesh_facenum[mid]
    tri = model.mesh_vert[v0 + model.mesh_face[f0 : f0 + nf]]  # [F, 3, 3]
    return abs(float(np.einsum("fi,fi->f", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum()) / 6)


def _volume(kind, size: np.ndarray) -> float:
    if kind == mujoco.mjtGeom.mjGEOM_BOX:
        return float(8 * np.prod(size))
    cylinder = math.pi * size[0] ** 2 * 2 * size[1]
    if kind == mujoco.mjtGeom.mjGEOM_CAPSULE:
        return cylinder + 4 / 3 * math.pi * size[0] ** 3
    return cylinder


def _fit(spec: mujoco.MjSpec, model: mujoco.MjModel, to_fit: list, replaced: set) -> list[str]:
    """Replace the collision meshes `to_fit` ((body, index, compiled geom id, label) each)
    by the primitive MuJoCo fits to each (to its inertia-equivalent box or to its bounding
    box, `fitaabb`) closest to the mesh in volume; a line per mesh."""
    trials = {}
    for kind in _FITS:
        for aabb in (False, True):
            copy = spec.copy()
            copy.compiler.fitaabb = aabb
            for body, k, _, _ in to_fit:
                list(copy.body(body).geoms)[k].type = kind
            try:
                trials[kind, aabb] = copy.compile()
            except ValueError:  # a degenerate fit (a capsule of no length): not a candidate
                continue
    if not trials:
        raise spec_error("collision", "MuJoCo fits no primitive to these collision meshes")
    lines = []
    for body, k, g, label in to_fit:
        mesh = _mesh_volume(model, g)
        errors = {
            key: _volume(key[0], fitted.geom_size[g]) / max(mesh, 1e-300) - 1.0
            for key, fitted in trials.items()
        }
        best = min(errors, key=lambda key: abs(errors[key]))
        fitted = trials[best]
        geom = list(spec.body(body).geoms)[k]
        replaced.add(geom.meshname)
        geom.type = best[0]
        geom.size = fitted.geom_size[g]
        _set_frame(geom, fitted.geom_pos[g], fitted.geom_quat[g])
        geom.meshname = ""
        lines.append(
            f"collision mesh {label} of body '{body}': a {_FITS[best[0]]}, its volume "
            f"{round(errors[best], 3) + 0.0:+.1%} of the mesh's"
        )
    return lines
