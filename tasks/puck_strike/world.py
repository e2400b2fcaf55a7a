"""The puck-strike world: the UR5e with its Robotiq 2F-85 holding a short bat, a long table and a
puck on it.

- The table (:data:`TABLE`): its top at the robot's table height (0.78 m, the UR5e's base plate), x 0.15 to
  2.2 m and y -0.5 to 0.75 m: longer than the robot's own tabletop (which ends at x 0.85 m), so that the
  puck can slide to where the arm does not reach. A 4 cm plate, drawn legs.
- The puck (:data:`PUCK_RADIUS`, :data:`PUCK_HEIGHT`, :data:`PUCK_MASS`: an ice-hockey puck's size and
  mass, 76 mm across, 25 mm thick, 0.16 kg) is a free cylinder that starts at rest on the table at
  :data:`PUCK_START`. Its sliding friction with the table is :data:`PUCK_FRICTION` (the puck's geom has the
  higher ``priority``, so its friction is the contact's; an assumption: a smooth plastic puck on a laminated
  table top), with small torsional and rolling friction.
- The bat: a handle held in the gripper along the tool axis (drawn only: it does not collide with the
  fingers that hold it) and a round blade at its end: a capsule of radius :data:`HEAD_RADIUS` whose axis,
  2 x :data:`BLADE_HALF_WIDTH` long, lies across the tool's closing axis, :data:`HEAD_REACH` from the pinch
  point. A blade across the strike meets the puck's side at one point at the blade's height, so a strike at
  the puck's mid-height pushes it without tipping it. The bat is welded to the hand (the fingers hold it
  rigidly) and weightless to the actuators, as the robot is (``gravity_compensation``). The blade collides
  with the puck, the table and the robot; its contacts are soft and critically damped
  (:data:`HEAD_SOLREF`: a padded blade; a stiffer, lively contact made the puck's speed depend on where in
  a 2 ms step the impact began). The site ``head`` is the centre of the blade's axis.

Sensors, every step: the puck's position (``puck_position``) and linear velocity (``puck_velocity``) in the
world. The world integrates with MuJoCo's ``implicit`` integrator at the robot's own 2 ms timestep.
"""

from __future__ import annotations

import mujoco
import numpy as np

import besman.robots as robots
from besman.sim.world import Surface, World

ROBOT = "ur5e"
TABLE = Surface("table", 0.78, (0.15, 2.2), (-0.5, 0.75))
TABLE_PLATE = 0.04  # m, the top's thickness
PUCK_RADIUS = 0.038  # m
PUCK_HEIGHT = 0.025  # m
PUCK_MASS = 0.16  # kg
PUCK_FRICTION = (0.2, 0.002, 0.0001)  # sliding, torsional, rolling
# Where the puck starts: in front of the hand in the arm's vertical plane at pan -90 deg (y = 0.134 m).
PUCK_START = (0.55, 0.134)
HEAD_REACH = 0.19  # m from the pinch point to the blade's axis
HEAD_RADIUS = 0.01  # m, the blade's
BLADE_HALF_WIDTH = 0.04  # m, the blade's axis is 8 cm long (10 cm with its round ends)
HEAD_SOLREF = (0.03, 1.0)  # time constant (s), damping ratio of the blade's contacts
HEAD_MASS = 0.15  # kg


def puck_strike_world() -> World:
    """The UR5e holding the bat in front of the long table, the puck at rest at :data:`PUCK_START`."""
    description = robots.describe(ROBOT)
    spec = robots.build_spec(description)
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICIT
    (x0, x1), (y0, y1), top = TABLE.x, TABLE.y, TABLE.height
    wood = [0.55, 0.4, 0.28, 1]
    spec.worldbody.add_geom(
        name="table",
        type=mujoco.mjtGeom.mjGEOM_BOX,
        pos=[(x0 + x1) / 2, (y0 + y1) / 2, top - TABLE_PLATE / 2],
        size=[(x1 - x0) / 2, (y1 - y0) / 2, TABLE_PLATE / 2],
        rgba=wood,
    )
    leg = (top - TABLE_PLATE) / 2
    for x in (x0 + 0.04, x1 - 0.04):
        for y in (y0 + 0.04, y1 - 0.04):
            spec.worldbody.add_geom(
                type=mujoco.mjtGeom.mjGEOM_BOX,
                pos=[x, y, leg],
                size=[0.025, 0.025, leg],
                rgba=[0.45, 0.32, 0.22, 1],
                contype=0,
                conaffinity=0,
            )
    hand = spec.body("gripper/base")
    pinch = np.array(spec.site("gripper/pinch").pos, dtype=float)
    bat = hand.add_body(name="bat", pos=pinch.tolist())
    bat.gravcomp = 1.0
    bat.add_geom(
        name="bat_handle",
        type=mujoco.mjtGeom.mjGEOM_CAPSULE,
        fromto=[0, 0, -0.03, 0, 0, HEAD_REACH - HEAD_RADIUS],
        size=[0.012, 0, 0],
        contype=0,
        conaffinity=0,
        mass=0.05,
        rgba=[0.55, 0.4, 0.25, 1],
    )
    bat.add_geom(
        name="bat_head",
        type=mujoco.mjtGeom.mjGEOM_CAPSULE,
        fromto=[-BLADE_HALF_WIDTH, 0, HEAD_REACH, BLADE_HALF_WIDTH, 0, HEAD_REACH],
        size=[HEAD_RADIUS, 0, 0],
        mass=HEAD_MASS,
        rgba=[0.85, 0.2, 0.15, 1],
        solref=list(HEAD_SOLREF),
        priority=2,
        friction=[0.3, 0.005, 0.0001],
        condim=3,
    )
    bat.add_site(name="head", pos=[0, 0, HEAD_REACH], size=[0.004, 0, 0])
    puck = spec.worldbody.add_body(name="puck", pos=[*PUCK_START, top + PUCK_HEIGHT / 2])
    puck.add_freejoint(name="puck")
    puck.add_geom(
        name="puck",
        type=mujoco.mjtGeom.mjGEOM_CYLINDER,
        size=[PUCK_RADIUS, PUCK_HEIGHT / 2, 0],
        mass=PUCK_MASS,
        rgba=[0.1, 0.1, 0.12, 1],
        friction=list(PUCK_FRICTION),
        priority=1,
        condim=6,
    )
    spec.add_sensor(
        name="puck_position",
        type=mujoco.mjtSensor.mjSENS_FRAMEPOS,
        objtype=mujoco.mjtObj.mjOBJ_BODY,
        objname="puck",
    )
    spec.add_sensor(
        name="puck_velocity",
        type=mujoco.mjtSensor.mjSENS_FRAMELINVEL,
        objtype=mujoco.mjtObj.mjOBJ_BODY,
        objname="puck",
    )
    return World(description, spec, surfaces=(TABLE,))
