"""Compose a robot's MJCF with a terrain into one compiled MuJoCo model, and cache it.

The robot plugin gives the robot alone (no floor). Here `mujoco.MjSpec` adds the terrain
(plane, tilted plane or height field from `coadapt_core.physics.terrain`), one contact sensor per
foot, the physics step, and for `fixed_base` removes the free joint. Compiled models are
cached per (design, terrain, fixed_base, physics_dt): environments sharing a design share a
compilation, and the next PSO iteration re-uses what it has seen. MuJoCo is imported by the
functions that compile, not with the module (docs/architecture.md, "Start-up").
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass
from typing import TYPE_CHECKING

from coadapt_core.errors import UserError
from coadapt_core.physics.terrain import Terrain, make_terrain
from coadapt_core.robot import Robot, RobotModel

if TYPE_CHECKING:
    import mujoco
    import numpy as np

#: name prefix of everything this module adds, so it never clashes with a robot's names
PREFIX = "coadapt_"
TERRAIN_GEOM = PREFIX + "terrain"
FLOOR_GEOM = PREFIX + "floor"
HFIELD = PREFIX + "hfield"
#: contact sensor data bits (mjtConDataType: found=1, force=2) and reduce mode 3 (netforce):
#: per foot, the number of contacts and the net contact force, world frame
_CONTACT_DATA = 1 | 2
_CONTACT_REDUCE_NETFORCE = 3
CONTACT_SENSOR_DIM = 4  # found, fx, fy, fz
#: the random terrain's height field sits on a safety floor this far below z = 0, so a
#: robot walking off the field's edge lands instead of falling forever
FLOOR_BELOW_FIELD = 0.001
#: how deep the height field's box extends below its lowest vertex (collision volume)
HFIELD_BASE_DEPTH = 0.1


@dataclass
class CompiledDesign:
    """One design on one terrain: the robot facts and its compiled model."""

    robot_model: RobotModel
    model: mujoco.MjModel
    base_body_id: int
    foot_body_ids: np.ndarray  # [L]
    qpos_adr: np.ndarray  # [J] qpos address of each actuated joint, in joint_names order
    dof_adr: np.ndarray  # [J]
    actuator_ids: np.ndarray  # [J] actuator driving each joint, in joint_names order
    foot_xy_offset: np.ndarray  # [L, 2] foot body origin relative to the base at the default pose
    foot_radius: float  # m, horizontal reach of a foot's contact points around its origin


def terrain_normal(terrain: Terrain) -> np.ndarray:
    """[3] upward unit normal of the terrain's mean plane."""
    import numpy as np

    a = terrain.slope_radians
    return np.array([-math.sin(a), 0.0, math.cos(a)])


def compose_spec(
    robot_model: RobotModel, terrain: Terrain, *, physics_dt: float, fixed_base: bool
) -> mujoco.MjSpec:
    import mujoco

    spec = mujoco.MjSpec.from_string(robot_model.text("mjcf"))
    spec.option.timestep = physics_dt
    world = spec.worldbody
    if terrain.name == "random":
        # one [samples, samples] grid, row along y, column along x: the layout of MuJoCo's
        # hfield (row 0 at y = -size/2), stored normalised and scaled by the elevation
        grid = terrain.height_grid()
        n = terrain.samples
        spec.add_hfield(
            name=HFIELD,
            size=[terrain.size / 2, terrain.size / 2, terrain.max_height, HFIELD_BASE_DEPTH],
            nrow=n,
            ncol=n,
            userdata=(grid / terrain.max_height).ravel().tolist(),
        )
        world.add_geom(
            name=TERRAIN_GEOM,
            type=mujoco.mjtGeom.mjGEOM_HFIELD,
            hfieldname=HFIELD,
            contype=0,
            conaffinity=1,
        )
        world.add_geom(
            name=FLOOR_GEOM,
            type=mujoco.mjtGeom.mjGEOM_PLANE,
            size=[0, 0, 1],
            pos=[0, 0, -FLOOR_BELOW_FIELD],
            contype=0,
            conaffinity=1,
        )
    else:
        # slope: the plane rotated about y by -angle so it rises along +x
        half = -terrain.slope_radians / 2
        world.add_geom(
            name=TERRAIN_GEOM,
            type=mujoco.mjtGeom.mjGEOM_PLANE,
            size=[0, 0, 1],
            quat=[math.cos(half), 0.0, math.sin(half), 0.0],
            contype=0,
            conaffinity=1,
        )
    # The envelope in coadapt_core.physics.actuation is the one torque limit; MuJoCo's own ctrl
    # clamp would be a second, possibly different one (rounding of the MJCF's ctrlrange).
    for act in spec.actuators:
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
    for foot in robot_model.foot_bodies:
        # subtree of the foot against every world geom (the terrain and the safety floor)
        spec.add_sensor(
            name=PREFIX + "contact_" + foot,
            type=mujoco.mjtSensor.mjSENS_CONTACT,
            objtype=mujoco.mjtObj.mjOBJ_XBODY,
            objname=foot,
            reftype=mujoco.mjtObj.mjOBJ_BODY,
            refname="world",
            intprm=[_CONTACT_DATA, _CONTACT_REDUCE_NETFORCE, 1],
        )
    if fixed_base:
        base = spec.body(robot_model.base_body)
        for joint in list(base.joints):
            if joint.type == mujoco.mjtJoint.mjJNT_FREE:
                spec.delete(joint)
    return spec


def compile_design(
    robot: Robot,
    design: np.ndarray,
    terrain: Terrain,
    *,
    physics_dt: float,
    fixed_base: bool,
    robot_model: RobotModel | None = None,
) -> CompiledDesign:
    import mujoco
    import numpy as np

    rm = robot_model if robot_model is not None else robot.build(design)
    spec = compose_spec(rm, terrain, physics_dt=physics_dt, fixed_base=fixed_base)
    try:
        model = spec.compile()
    except ValueError as exc:
        raise UserError(
            f"design {np.round(design, 4).tolist()}: MuJoCo cannot compile its model: {exc}",
            field="design",
        ) from None
    if terrain.name == "random":
        # exact heights (the compiler may renormalise user elevation data)
        hid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_HFIELD, HFIELD)
        start = model.hfield_adr[hid]
        values = (terrain.height_grid() / terrain.max_height).ravel()
        model.hfield_data[start : start + values.size] = values
    base_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, rm.base_body)
    if base_id < 0:
        raise UserError(f"robot model has no base body '{rm.base_body}'", field="robot")
    if not fixed_base and (
        model.body_jntnum[base_id] < 1
        or model.jnt_type[model.body_jntadr[base_id]] != mujoco.mjtJoint.mjJNT_FREE
    ):
        raise UserError(f"robot base body '{rm.base_body}' has no free joint", field="robot")
    foot_ids = np.array(
        [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f) for f in rm.foot_bodies]
    )
    jids = np.array(
        [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in rm.joint_names]
    )
    if np.any(jids < 0) or np.any(foot_ids < 0):
        raise UserError("robot model lacks a joint or foot body it names", field="robot")
    actuator_ids = np.full(len(jids), -1)
    for a in range(model.nu):
        if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT:
            hit = np.flatnonzero(jids == model.actuator_trnid[a, 0])
            if hit.size:
                actuator_ids[hit[0]] = a
    if np.any(actuator_ids < 0):
        missing = [rm.joint_names[i] for i in np.flatnonzero(actuator_ids < 0)]
        raise UserError(f"robot model has no actuator for joints {missing}", field="robot")
    # foot placement at the default pose, base at the origin (for spawning on terrain)
    data = mujoco.MjData(model)
    qadr = model.jnt_qposadr[jids]
    if not fixed_base:
        data.qpos[:7] = [0, 0, 0, 1, 0, 0, 0]
    data.qpos[qadr] = rm.default_joint_pos
    mujoco.mj_kinematics(model, data)
    foot_xy = data.xpos[foot_ids, :2] - data.xpos[base_id, :2]
    pts = np.asarray(rm.foot_contact_points, dtype=float).reshape(-1, 3)
    radius = float(np.max(np.linalg.norm(pts[:, :2], axis=1))) if len(pts) else 0.15
    return CompiledDesign(
        robot_model=rm,
        model=model,
        base_body_id=base_id,
        foot_body_ids=foot_ids,
        qpos_adr=qadr.astype(int),
        dof_adr=model.jnt_dofadr[jids].astype(int),
        actuator_ids=actuator_ids,
        foot_xy_offset=foot_xy,
        foot_radius=radius,
    )


class ModelCache:
    """Compiled designs keyed by (robot class and name, design, terrain, fixed_base,
    physics_dt), least recently used evicted beyond `capacity`."""

    def __init__(self, capacity: int = 256):
        self.capacity = capacity
        self._items: OrderedDict[tuple, CompiledDesign] = OrderedDict()
        self.hits = 0
        self.misses = 0

    def get(
        self,
        robot: Robot,
        design: np.ndarray,
        terrain: Terrain,
        *,
        physics_dt: float,
        fixed_base: bool,
    ) -> CompiledDesign:
        # the robot's class as well as its name: a subclass (a test's planted fault, a
        # variant) named like its parent builds other models and must not read the parent's
        import numpy as np

        key = (
            type(robot),
            robot.name,
            tuple(np.round(np.asarray(design, dtype=float), 12)),
            terrain,
            fixed_base,
            physics_dt,
        )
        item = self._items.get(key)
        if item is not None:
            self.hits += 1
            self._items.move_to_end(key)
            return item
        self.misses += 1
        item = compile_design(robot, design, terrain, physics_dt=physics_dt, fixed_base=fixed_base)
        self._items[key] = item
        if len(self._items) > self.capacity:
            self._items.popitem(last=False)
        return item


def terrain_for(name: str, seed: int) -> Terrain:
    return make_terrain(name, seed=seed)
