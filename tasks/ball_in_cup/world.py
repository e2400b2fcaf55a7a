"""The ball-in-a-cup world: the UR5e with its Robotiq 2F-85, a cup held by its handle beyond the fingers, and
a ball on a string tied under the cup's bottom.

- The cup (inner radius :data:`CUP_RADIUS`, inner depth :data:`CUP_DEPTH`, a 5 mm wall of 16 boxes and a
  1 cm bottom plate) sits at the end of a 9 cm handle that continues the gripper's tool axis; the cup's axis
  is the tool frame's -x axis, which points up in the task's start pose. Cup and handle are part of the
  hand's body (welded: the fingers hold the handle rigidly) and weightless to the actuators, as the robot is
  (``gravity_compensation``). Its frame, the site ``cup``, is the centre of the cup's inner bottom with z
  along the cup's axis, towards the opening.
- The ball (diameter 4 cm, 25 g, a wooden ball's) is a free body. It collides with the cup only (contact
  type bit 2): not with the robot, the floor or the string.
- The string is massless: a spatial tendon from the knot under the cup's bottom (site ``knot``, 1 cm below
  the inner bottom) to the ball's centre whose length is limited to the string's length (a one-sided
  constraint: slack while shorter, taut at its length). Its length is set per rollout
  (:func:`set_string_length`); it passes through the cup's rim rather than wrapping round it.

The world integrates with MuJoCo's ``implicit`` integrator at the robot's own 2 ms timestep.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

import besman.robots as robots
from besman.sim.world import World

ROBOT = "ur5e"
CUP_RADIUS = 0.045  # m, inner radius (9 cm inner diameter)
CUP_DEPTH = 0.08  # m, from the inner bottom to the rim
CUP_WALL = 0.005  # m
CUP_BOTTOM = 0.01  # m, thickness of the bottom plate; the knot is under it
HANDLE = 0.09  # m from the gripper's pinch point to the cup's outer wall
BALL_RADIUS = 0.02  # m
BALL_MASS = 0.025  # kg
CONTACT_BIT = 2  # the cup's and the ball's contact type and affinity: they collide with each other only
WALL_BOXES = 16
STRING = "string"


def ball_in_cup_world(string_length: float = 0.4) -> World:
    """The UR5e holding the cup, with the ball on a string of ``string_length`` m (knot to ball centre)."""
    description = robots.describe(ROBOT)
    spec = robots.build_spec(description)
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICIT
    hand = spec.body("gripper/base")
    pinch = np.array(spec.site("gripper/pinch").pos, dtype=float)
    centre = pinch + np.array([0.0, 0.0, HANDLE + CUP_RADIUS + CUP_WALL])
    # The cup's frame in the hand's: z (the cup's axis) along the tool's -x, x along the tool's z.
    cup = hand.add_body(name="cup", pos=centre.tolist(), quat=[math.sqrt(0.5), 0.0, -math.sqrt(0.5), 0.0])
    cup.gravcomp = 1.0
    colour = [0.85, 0.2, 0.15, 1.0]
    solid = {"contype": CONTACT_BIT, "conaffinity": CONTACT_BIT, "rgba": colour, "condim": 3}
    cup.add_geom(
        name="cup_bottom",
        type=mujoco.mjtGeom.mjGEOM_CYLINDER,
        pos=[0, 0, -CUP_BOTTOM / 2],
        size=[CUP_RADIUS + CUP_WALL, CUP_BOTTOM / 2, 0],
        mass=0.03,
        **solid,
    )
    ring = CUP_RADIUS + CUP_WALL / 2
    half_width = (CUP_RADIUS + CUP_WALL) * math.tan(math.pi / WALL_BOXES)
    for k in range(WALL_BOXES):
        angle = 2 * math.pi * k / WALL_BOXES
        cup.add_geom(
            name=f"cup_wall_{k}",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            pos=[ring * math.cos(angle), ring * math.sin(angle), CUP_DEPTH / 2],
            quat=[math.cos(angle / 2), 0, 0, math.sin(angle / 2)],
            size=[CUP_WALL / 2, half_width, CUP_DEPTH / 2],
            mass=0.005,
            **solid,
        )
    # The handle, from the pinch point to the cup's wall (drawn only; in the cup's frame it runs along -x).
    cup.add_geom(
        name="cup_handle",
        type=mujoco.mjtGeom.mjGEOM_CAPSULE,
        fromto=[
            -(CUP_RADIUS + CUP_WALL),
            0,
            CUP_DEPTH / 3,
            -(CUP_RADIUS + CUP_WALL + HANDLE),
            0,
            CUP_DEPTH / 3,
        ],
        size=[0.008, 0, 0],
        contype=0,
        conaffinity=0,
        mass=0.02,
        rgba=[0.55, 0.4, 0.25, 1],
    )
    cup.add_site(name="cup", pos=[0, 0, 0])
    cup.add_site(name="knot", pos=[0, 0, -CUP_BOTTOM], size=[0.004, 0, 0])
    ball = spec.worldbody.add_body(name="ball", pos=[0.5, 0.134, 0.5])
    ball.add_freejoint(name="ball")
    ball.add_geom(
        name="ball",
        type=mujoco.mjtGeom.mjGEOM_SPHERE,
        size=[BALL_RADIUS, 0, 0],
        mass=BALL_MASS,
        rgba=[0.9, 0.8, 0.3, 1],
        contype=CONTACT_BIT,
        conaffinity=CONTACT_BIT,
        condim=3,
    )
    ball.add_site(name="ball_centre", pos=[0, 0, 0], size=[0.003, 0, 0])
    string = spec.add_tendon(
        name=STRING, limited=True, range=[0.0, string_length], width=0.0015, rgba=[0.9, 0.9, 0.9, 1]
    )
    string.solref_limit = [0.005, 1.0]
    string.wrap_site("knot")
    string.wrap_site("ball_centre")
    # Where the ball is in the cup's frame, and how fast it moves in the world, every step.
    spec.add_sensor(
        name="ball_in_cup",
        type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
        objtype=mujoco.mjtObj.mjOBJ_BODY,
        objname="ball",
        reftype=mujoco.mjtObj.mjOBJ_SITE,
        refname="cup",
    )
    return World(description, spec)


def set_string_length(model: mujoco.MjModel, length: float) -> None:
    """Sets the string's length (m, knot to ball centre) on a compiled model."""
    model.tendon_range[model.tendon(STRING).id] = [0.0, length]
