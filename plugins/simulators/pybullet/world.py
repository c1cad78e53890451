"""The world each PyBullet environment lives alone in: one DIRECT physics client with
gravity, the time step and a deterministic solver, and its own copy of the terrain at the
origin (a plane, a slope, or a height field over a safety floor)."""

from __future__ import annotations

import numpy as np
import pybullet as p

from coadapt_core.physics.terrain import Terrain

#: gravity, m/s^2 (MuJoCo's default)
GRAVITY = 9.81
#: random terrain: the safety floor lies this far below z = 0 (as in MuJoCo), m
FLOOR_BELOW_FIELD = 0.001


def open_world(
    terrain: Terrain, physics_dt: float, solver_iterations: int
) -> tuple[int, list[int]]:
    """A new DIRECT client set up for `physics_dt` steps, and the terrain's bodies in it."""
    client = p.connect(p.DIRECT)
    if client < 0:
        raise RuntimeError("pybullet could not open a DIRECT physics client")
    return client, renew_world(client, terrain, physics_dt, solver_iterations)


def renew_world(
    client: int, terrain: Terrain, physics_dt: float, solver_iterations: int
) -> list[int]:
    """Empty `client`'s world (`resetSimulation`), set it up again and return the terrain's
    new bodies. A robot is reloaded into a renewed world, never beside a removed body:
    Bullet keeps the tree `calculateMassMatrix` and `calculateJacobian` compute on, one per
    body, keyed by the body's address, until its world goes (`removeBody` leaves it), so a
    body loaded where a removed one lay was given the removed one's masses and inertias.
    That happened by chance, in some processes and not others: the armature correction
    then used the previous design's or CoM shift's mass matrix for a whole episode."""
    p.resetSimulation(physicsClientId=client)
    p.setGravity(0.0, 0.0, -GRAVITY, physicsClientId=client)
    p.setTimeStep(physics_dt, physicsClientId=client)
    p.setPhysicsEngineParameter(
        numSubSteps=0,
        numSolverIterations=solver_iterations,
        deterministicOverlappingPairs=1,
        physicsClientId=client,
    )
    return create_ground(client, terrain)


def create_ground(client: int, terrain: Terrain) -> list[int]:
    """The terrain's bodies in `client`: the ground first, then any safety floor."""
    t = terrain
    bodies = []
    if t.name == "random":
        grid = t.height_grid()  # [rows along y, cols along x]
        shape = p.createCollisionShape(
            p.GEOM_HEIGHTFIELD,
            meshScale=[t.resolution, t.resolution, 1.0],
            heightfieldData=grid.ravel().tolist(),
            numHeightfieldRows=t.samples,
            numHeightfieldColumns=t.samples,
            physicsClientId=client,
        )
        # Bullet centres a height field on its bounding box, heights included
        position = [0.0, 0.0, 0.5 * (float(grid.min()) + float(grid.max()))]
        # a safety floor just below the field (as in MuJoCo): a robot walking off its
        # edge lands instead of falling forever
        floor = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=client)
        bodies.append(
            p.createMultiBody(
                0, floor, basePosition=[0.0, 0.0, -FLOOR_BELOW_FIELD], physicsClientId=client
            )
        )
    else:
        angle = t.slope_radians  # 0 on flat ground; the slope rises along +x
        shape = p.createCollisionShape(
            p.GEOM_PLANE,
            planeNormal=[-np.sin(angle), 0.0, np.cos(angle)],
            physicsClientId=client,
        )
        position = [0.0, 0.0, 0.0]
    bodies.insert(0, p.createMultiBody(0, shape, basePosition=position, physicsClientId=client))
    for ground in bodies:
        # Bullet multiplies the two bodies' coefficients: 1 on the ground makes the
        # robot's own friction and restitution the ones in force
        p.changeDynamics(
            ground,
            -1,
            lateralFriction=1.0,
            restitution=1.0,
            spinningFriction=0.0,
            rollingFriction=0.0,
            physicsClientId=client,
        )
    return bodies
