"""A spec robot's `RobotModel` per design: the scaled model, its motors, limits and gains,
its standing height, contact points and the URDF that PyBullet and Pinocchio read."""

from __future__ import annotations

from functools import cached_property
from types import MappingProxyType

import mujoco
import numpy as np
from coadapt_plugins.robots.specs import model as M
from coadapt_plugins.robots.specs.kinematics import LegKinematics, build_chain
from coadapt_plugins.robots.specs.loops import close_loops
from coadapt_plugins.robots.specs.spec import (
    DESIGN_DECIMALS,
    Parameter,
    RobotSpec,
    joint_values,
    match_value,
    readonly,
    spec_error,
)

from coadapt_core.robot import RobotModel


def mass_rule_text(p: Parameter) -> str:
    """One line: how parameter `p` changes the mass and inertia of the bodies it stretches."""
    if p.mass == "fixed":
        return "mass, centre of mass and inertia unchanged (rule 'fixed')"
    share = f"{p.stretch_share:g} of the body's mass" if p.stretch_share < 1 else "the body's mass"
    return (
        f"{share} stretches with the link (mass x scale, distribution stretched along it), "
        "the rest is a point mass at the body's origin; a body without an explicit inertial: "
        "recomputed from its stretched geoms"
    )


def lowest_points(model: mujoco.MjModel, body: int, pos: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """[k, 3] the points of `body`'s collision geoms lowest along the z of the frame given by
    (pos, rot) of each geom (one per sphere or capsule end, four per box face), in that
    frame, for geoms at `pos` [G, 3] with axes `rot` [G, 3, 3]."""
    points = []
    for g in range(model.ngeom):
        if model.geom_bodyid[g] != body or not (model.geom_contype[g] or model.geom_conaffinity[g]):
            continue
        centre, axes, size = pos[g], rot[g], model.geom_size[g]
        kind = int(model.geom_type[g])
        if kind == int(mujoco.mjtGeom.mjGEOM_SPHERE):
            points.append(centre - [0.0, 0.0, size[0]])
        elif kind == int(mujoco.mjtGeom.mjGEOM_CAPSULE):
            ends = [centre + e * size[1] * axes[:, 2] for e in (-1.0, 1.0)]
            low = min(end[2] for end in ends)
            points += [end - [0.0, 0.0, size[0]] for end in ends if end[2] < low + 1e-9]
        else:  # boxes and the rest: the corners of the geom's bounding box
            half = model.geom_aabb[g, 3:]
            corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
            world = centre + (corners * half + model.geom_aabb[g, :3]) @ axes.T
            low = world[:, 2].min()
            points += list(world[world[:, 2] < low + 1e-9])
    return np.array(points).reshape(-1, 3)


def _geom_frames(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """([G, 3], [G, 3, 3]) every geom's position and axes in its body's frame."""
    rot = np.zeros((model.ngeom, 9))
    for g in range(model.ngeom):
        mujoco.mju_quat2Mat(rot[g], model.geom_quat[g])
    return model.geom_pos.copy(), rot.reshape(-1, 3, 3)


class SpecBuilder:
    """Everything loaded once per spec robot; `model(design)` builds one design."""

    def __init__(self, spec: RobotSpec):
        self.spec = spec
        self.prepared = M.prepare(spec)
        M.check_names(spec, self.prepared)
        joints = self.prepared.joints
        self.torque, self.speed, self.types = self._motor_table(joints)
        self.gains = joint_values(spec.gains, joints, "gains")
        self._levelled: dict = {}  # each design's standing targets searched (`level`)

    def _motor_table(self, joints: list[str]):
        """Nominal (torque [J], speed [J], type per joint or None)."""
        spec = self.spec
        types = [match_value(spec.motor_joints, j) for j in joints]
        for param in spec.motor_parameters:
            for pattern in param.joints:
                hits = [k for k, j in enumerate(joints) if match_value({pattern: 1}, j)]
                if not hits:
                    raise spec_error("motors.parameters", f"'{pattern}' matches no joint")
                for k in hits:
                    types[k] = param.nominal
        torque, speed = [], []
        for k, joint in enumerate(joints):
            if types[k] is not None:
                torque.append(spec.motor_types[types[k]].torque)
                speed.append(spec.motor_types[types[k]].speed)
                continue
            t, v = match_value(spec.torque, joint), match_value(spec.speed, joint)
            if t is None or v is None:
                what = "limits.torque" if t is None else "limits.speed"
                raise spec_error(what, f"no entry matches joint '{joint}' and it has no motor type")
            torque.append(t)
            speed.append(v)
        return np.array(torque), np.array(speed), types

    @cached_property
    def kinematics(self) -> LegKinematics:
        model = self.prepared.spec.compile()
        legs = [(leg.foot, leg.hip) for leg in self.spec.legs]
        links = [set(p.links) for p in self.spec.parameters]
        nominal = np.array([p.nominal for p in self.spec.parameters])
        if self.spec.loops:  # four-bar legs: both halves of each, the motors returned
            from coadapt_plugins.robots.specs.loopkin import LoopKinematics

            try:
                return LoopKinematics(
                    model, self.prepared, self.spec, links, nominal, DESIGN_DECIMALS
                )
            except ValueError as exc:
                raise spec_error("legs", str(exc)) from None
        try:
            chain = build_chain(
                model, self.prepared.base, self.prepared.joints, legs, links,
                self.prepared.standing, nominal, DESIGN_DECIMALS,
            )  # fmt: skip
        except ValueError as exc:
            raise spec_error("legs", str(exc)) from None
        return LegKinematics(chain)

    def _design_types(self, design: np.ndarray) -> list[int | None]:
        types = list(self.types)
        plain = len(self.spec.parameters)
        if design.shape[0] == plain:
            return types
        joints = self.prepared.joints
        for value, param in zip(design[plain:], self.spec.motor_parameters, strict=True):
            for k, joint in enumerate(joints):
                if any(match_value({p: 1}, joint) for p in param.joints):
                    types[k] = int(round(value))
        return types

    def edited(self, design: np.ndarray) -> tuple[mujoco.MjSpec, list[int | None]]:
        """The model spec of one design (base at the origin) and its motor type per joint."""
        spec = self.prepared.spec.copy()
        for k, p in enumerate(self.spec.parameters):
            s = float(design[k]) / p.nominal
            for m, (parent, child) in enumerate(p.links):
                M.scale_link(spec, parent, child, s, p, f"design[{k}].links[{m}]")
        types = self._design_types(design)
        for joint, kind, nominal in zip(self.prepared.joints, types, self.types, strict=True):
            if kind is not None and kind != nominal:
                delta = self.spec.motor_types[kind].mass - self.spec.motor_types[nominal].mass
                if delta:
                    M.add_point_mass(spec, joint, delta)
        spec.body(self.prepared.base).pos = [0.0, 0.0, 0.0]
        return spec, types

    def model(self, design: np.ndarray) -> RobotModel:
        from coadapt_plugins.robots.specs.mjcf import mjcf_text
        from coadapt_plugins.robots.specs.urdf import urdf_text

        spec, types = self.edited(design)
        torque, speed = self.torque.copy(), self.speed.copy()
        for k, kind in enumerate(types):
            if kind is not None:
                torque[k] = self.spec.motor_types[kind].torque
                speed[k] = self.spec.motor_types[kind].speed
        joints = self.prepared.joints
        compiled = spec.compile()
        pose = self.standing_pose(design, compiled)
        if self.spec.loops:  # closed at the standing pose, the passive hinges' zero there
            p = self.prepared
            compiled = close_loops(
                spec, compiled, self.spec, joints, pose, p.passive, p.passive_seeds
            )
        height, contact = self._standing(compiled, pose)
        compiled.body_pos[compiled.body(self.prepared.base).id] = [0.0, 0.0, height]
        formats = {"mjcf": mjcf_text(compiled, self.spec.name, joints, torque)}
        files: dict[str, str] = {}
        urdf, why_not = urdf_text(compiled, self.spec.name, joints, torque, speed, files)
        if urdf is not None:
            formats["urdf"] = urdf
            formats.update({f"urdf:{name}": text for name, text in files.items()})
        kp, kd = self._gains(design)
        lower, upper = self._limits(compiled)
        return RobotModel(
            design=readonly(design),
            formats=MappingProxyType(formats),
            base_body=self.prepared.base,
            joint_names=list(joints),
            foot_bodies=[leg.foot for leg in self.spec.legs],
            default_joint_pos=readonly(pose),
            kp=readonly(kp),
            kd=readonly(kd),
            torque_limit=readonly(torque),
            speed_limit=readonly(speed),
            joint_lower=readonly(lower),
            joint_upper=readonly(upper),
            standing_base_height=float(height),
            total_mass=float(compiled.body_subtreemass[compiled.body(self.prepared.base).id]),
            foot_contact_points=readonly(contact),
            info=self._info(design, compiled, types, why_not),
        )

    def stand_targets(self, designs, level: bool = True):
        """[n, L, 3] each foot relative to its hip (base frame) when the standing pose is
        solved per design (`standing_pose.solve`): under the hip (x 0), at the nominal
        pose's lateral offset, STANDING_SHARE of the leg's length down; the leg's length is
        its scaled links' lengths summed (its chain below the hip when none is scaled). With
        `level`, a design whose IK answer there leaves a joint outside its range or a sole
        tilted gets the nearest share that does not (`level.level_targets`)."""
        import torch
        from coadapt_plugins.robots.specs.level import level_targets

        kin = self.kinematics
        c = kin.chain
        nominal = torch.as_tensor(self._nominal_plain()[None], dtype=torch.float64)
        rel = kin.standing(nominal)[0]  # [1, L, 3]
        scales = kin.scales(designs)  # [n, L, E]
        lengths = torch.linalg.norm(c.pos, dim=-1)  # [L, E]
        scaled = (c.scale.abs().sum(dim=-1) > 0).to(torch.float64)  # [L, E]
        below = (torch.arange(c.pos.shape[1])[None, :] > c.hip_element[:, None]).to(torch.float64)
        mask = torch.where(scaled.sum(dim=-1, keepdim=True) > 0, scaled, below)
        leg = (scales * lengths * mask).sum(dim=-1)  # [n, L]
        out = torch.zeros(designs.shape[0], c.num_legs, 3, dtype=torch.float64)
        out[..., 1] = rel[0, :, 1]
        out[..., 2] = -self.spec.standing_share * leg
        if not level or self.spec.loops:  # a four-bar's motors: no range or sole to keep
            return out
        return level_targets(
            kin, designs, out, self.spec.standing_share, *self._ranges, self._levelled
        )

    @cached_property
    def _ranges(self) -> tuple[np.ndarray, np.ndarray]:
        """([J], [J]) each joint's range at the nominal design (unlimited: +-inf)."""
        model = self.prepared.spec.compile()
        ids = [model.joint(j).id for j in self.prepared.joints]
        limited = model.jnt_limited[ids].astype(bool)
        lower = np.where(limited, model.jnt_range[ids, 0], -np.inf)
        return lower, np.where(limited, model.jnt_range[ids, 1], np.inf)

    def standing_pose(self, design: np.ndarray, model: mujoco.MjModel) -> np.ndarray:
        """[J] the design's standing pose: the spec's, or solved for it (`stand_targets`,
        the generic leg IK from the nominal pose), held inside the joint ranges."""
        if self.spec.standing_share is None:
            return self.prepared.standing
        import torch

        plain = torch.as_tensor(np.asarray(design[: len(self.spec.parameters)], dtype=float)[None])
        pose = self.kinematics.inverse(plain, self.stand_targets(plain))[0].numpy()
        ids = [model.joint(j).id for j in self.prepared.joints]
        lo, hi = model.jnt_range[ids, 0], model.jnt_range[ids, 1]
        limited = model.jnt_limited[ids].astype(bool)
        return np.where(limited, np.clip(pose, lo, hi), pose)

    def _standing(self, model: mujoco.MjModel, pose: np.ndarray) -> tuple[float, np.ndarray]:
        """(base height that puts the lowest foot point on the ground at the standing pose,
        [k, 3] the first foot's contact points: its geoms' lowest points along its own z, in
        its frame, unless the spec gives them)."""
        data = mujoco.MjData(model)
        data.qpos[:] = model.qpos0
        data.qpos[3:7] = [1.0, 0.0, 0.0, 0.0]
        for joint, angle in zip(self.prepared.joints, pose, strict=True):
            data.qpos[model.jnt_qposadr[model.joint(joint).id]] = angle
        mujoco.mj_kinematics(model, data)
        world = (data.geom_xpos, data.geom_xmat.reshape(-1, 3, 3))
        lows = []
        for k, leg in enumerate(self.spec.legs):
            body = model.body(leg.foot).id
            found = lowest_points(model, body, *world)
            if found.size == 0:
                raise spec_error(f"legs[{k}].foot", f"'{leg.foot}' has no collision geom")
            lows.append(found[:, 2].min())
        first = self.spec.legs[0]
        if first.contact_points is not None:
            points = np.array(first.contact_points)
        else:
            points = lowest_points(model, model.body(first.foot).id, *_geom_frames(model))
        return -float(min(lows)), points

    def _gains(self, design: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        kp = np.array([g["kp"] for g in self.gains])
        kd = np.array([g["kd"] for g in self.gains])
        k = self.spec.gain_scale_exponent
        if k:
            import torch

            kin = self.kinematics
            both = torch.tensor(
                np.stack([design[: len(self.spec.parameters)], self._nominal_plain()])
            )
            legs = -kin.default_foot_positions(both)[..., 2].mean(dim=-1)
            ratio = float(legs[0] / legs[1]) ** k
            kp, kd = kp * ratio, kd * ratio
        return kp, kd

    def _nominal_plain(self) -> np.ndarray:
        return np.array([p.nominal for p in self.spec.parameters])

    def _limits(self, model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
        lower, upper = [], []
        for k, joint in enumerate(self.prepared.joints):
            j = model.joint(joint).id
            if not model.jnt_limited[j]:
                raise spec_error("model", f"joint '{joint}' has no range; give it one")
            lower.append(model.jnt_range[j, 0])
            upper.append(model.jnt_range[j, 1])
            if not lower[-1] <= self.prepared.standing[k] <= upper[-1]:
                raise spec_error(
                    "standing_pose",
                    f"'{joint}' at {self.prepared.standing[k]:g} rad is outside its range "
                    f"[{lower[-1]:g}, {upper[-1]:g}]",
                )
        return np.array(lower), np.array(upper)

    def _info(self, design, model, types, why_not) -> dict:
        info: dict = {}
        units: dict = {}
        for k, p in enumerate(self.spec.parameters):
            for parent, child in p.links[:1]:
                length = float(np.linalg.norm(model.body_pos[model.body(child).id]))
                info[f"{p.name}_link_length"] = length
                info[f"{p.name}_link_mass"] = float(model.body_mass[model.body(parent).id])
                units[f"{p.name}_link_length"] = "m"
                units[f"{p.name}_link_mass"] = "kg"
            info[p.name] = float(design[k])
        info["mass_rules"] = {p.name: mass_rule_text(p) for p in self.spec.parameters}
        if any(t is not None for t in types):
            info["motor_types"] = [0 if t is None else int(t) for t in types]  # 0: no type
        info["armature"] = readonly(self.prepared.armature)
        info["joint_damping"] = readonly(self.prepared.damping)
        units.update(armature="kg m^2", joint_damping="N m s/rad")
        info["spec"] = str(self.spec.folder / "robot.yaml")
        if why_not:
            info["urdf"] = f"not written: {why_not}"
        if self.prepared.fits:
            info["collision_fit"] = "; ".join(self.prepared.fits)
        info["units"] = units
        return info
