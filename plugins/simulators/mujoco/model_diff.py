"""Which model fields a design changes: one `mujoco.batch.Batch` runs every design on the
first design's model, with the fields the others differ in expanded to per-row values. A
design that changes the model's structure (bodies, joints, geoms, actuators, field sizes)
cannot share the batch and is refused. MuJoCo is imported when fields are compared."""

from __future__ import annotations

from typing import TYPE_CHECKING

from coadapt_plugins.simulators.mujoco.compose import CompiledDesign

from coadapt_core.errors import UserError

if TYPE_CHECKING:  # numpy is imported where it is used: listing the plugins loads none
    pass

#: model fields never expanded per design (MuJoCo options, shared by the whole batch)
SKIP_PREFIX = ("opt.",)


def _same_collision_meshes(ref, other, design: list) -> None:
    """Mesh assets are the batch's, shared by every row: a design whose collision meshes
    differ in shape (a stretched link's) cannot share it. Visual meshes may differ."""
    import mujoco
    import numpy as np

    for g in range(ref.ngeom):
        if ref.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH:
            continue
        if not (ref.geom_contype[g] or ref.geom_conaffinity[g]):
            continue
        mesh = int(ref.geom_dataid[g])
        v0, nv = ref.mesh_vertadr[mesh], ref.mesh_vertnum[mesh]
        if other.mesh_vertnum[mesh] != nv or not np.array_equal(
            ref.mesh_vert[v0 : v0 + nv], other.mesh_vert[v0 : v0 + nv]
        ):
            name = ref.geom(g).name or f"number {g}"
            raise UserError(
                f"design {design} changes the shape of collision mesh '{name}'; one MuJoCo "
                "batch shares its mesh assets across designs: replace the mesh by a primitive "
                "(a spec robot: `collision: fit`)",
                field="designs",
            )


def diff_fields(reference: CompiledDesign, item: CompiledDesign) -> list[str]:
    """Model fields in which `item` differs from the batch's `reference` model."""
    import mujoco.batch
    import numpy as np

    ref, other = reference.model, item.model
    design = np.round(item.robot_model.design, 4).tolist()
    if (ref.nq, ref.nv, ref.nu, ref.nbody, ref.ngeom, ref.nsensordata) != (
        other.nq,
        other.nv,
        other.nu,
        other.nbody,
        other.ngeom,
        other.nsensordata,
    ) or not (
        np.array_equal(item.qpos_adr, reference.qpos_adr)
        and np.array_equal(item.actuator_ids, reference.actuator_ids)
        and np.array_equal(item.foot_body_ids, reference.foot_body_ids)
    ):
        raise UserError(
            f"design {design} changes the model's structure (bodies, joints, geoms or "
            "actuators); one MuJoCo batch needs designs that differ only in parameters",
            field="designs",
        )
    _same_collision_meshes(ref, other, design)
    out = []
    for name in mujoco.batch.MODEL_FIELDS:
        if name.startswith(SKIP_PREFIX):
            continue
        try:
            a, c = getattr(ref, name), getattr(other, name)
        except AttributeError:
            continue
        a, c = np.asarray(a), np.asarray(c)
        if a.shape != c.shape:
            raise UserError(
                f"design {design} changes the size of model field {name}; "
                "one MuJoCo batch needs designs that differ only in parameters",
                field="designs",
            )
        if not np.array_equal(a, c):
            out.append(name)
    return out
