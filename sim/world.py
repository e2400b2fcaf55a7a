"""Worlds: a robot model composed with a scene (furniture and objects) through MuJoCo's MjSpec.

A :class:`World` owns one compiled model, one ``MjData`` and the robot's description compiled against the
composed model (so group indices are right even after objects are added). It resets to a keyframe, and
reads and places objects by name. A task builds its world from one (the throwing task's:
:mod:`besman.tasks.throwing.world`) or uses:

- :func:`tabletop_world` - a robot (AILA by default) in front of a table with a raised shelf board on its
  right side, both where the robot's description puts them (its tabletop layout: AILA's table top at
  0.78 m, the shelf at 0.90 m), and graspable objects (a 6 cm wooden-like box of 0.2 kg by default).

Objects are free bodies; their poses are (x, y, z) plus a (w, x, y, z) quaternion.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import mujoco
import numpy as np

import besman.robots as robots
from besman.core.errors import InputError, UnknownNameError
from besman.core.moved import old_names
from besman.core.validation import checked, instance, items, number, text
from besman.robots import Pose, Robot, RobotDescription
from besman.robots.catalogue import ROBOT
from besman.robots.tabletop import Board, TabletopLayout
from besman.sim.objects import GraspableObject
from besman.sim.perturbations import Perception

DEFAULT_BOX = GraspableObject("box")


@dataclass(frozen=True)
class Surface:
    """A horizontal support: a box whose top face is at ``height`` and covers [x0, x1] x [y0, y1]."""

    name: str
    height: float
    x: tuple[float, float]
    y: tuple[float, float]

    def contains(self, x: float, y: float, margin: float = 0.0) -> bool:
        return self.x[0] + margin <= x <= self.x[1] - margin and self.y[0] + margin <= y <= self.y[1] - margin

    @classmethod
    def of(cls, name: str, board: Board) -> Surface:
        return cls(name, board.height, board.x, board.y)


class World:
    """A compiled scene with a robot; see the module documentation."""

    def __init__(
        self,
        robot: RobotDescription,
        spec: mujoco.MjSpec,
        objects: tuple[GraspableObject, ...] = (),
        surfaces: tuple[Surface, ...] = (),
        layout: TabletopLayout | None = None,
    ) -> None:
        self.spec = spec
        self.model = robots.compile_spec(spec, robot)
        self.data = mujoco.MjData(self.model)
        self.robot = Robot(robot, self.model)
        self.objects = {item.name: item for item in objects}
        self.surfaces = {surface.name: surface for surface in surfaces}
        self.layout = layout
        self.perception: Perception | None = None  # exact unless a run perturbs it (sim.perturbations)
        self.reset()

    def fork(self) -> World:
        """A world on the same model with a copy of this one's simulation state, to try motions out in
        without touching this one."""
        other = copy.copy(self)
        other.data = copy.copy(self.data)
        return other

    def home(self, joint_indices: np.ndarray) -> np.ndarray:
        """The positions of qpos entries ``joint_indices`` in the robot's home keyframe."""
        return self.model.key(self.robot.keyframe).qpos[joint_indices].copy()

    def reset(self, keyframe: str | None = None) -> None:
        """Resets the simulation to a keyframe (default: the robot's home) with objects where they were
        first placed."""
        self.robot.reset(self.data, keyframe)

    def _object_joint(self, name: str) -> int:
        if name not in self.objects:
            raise UnknownNameError(
                f"no object {name!r} in the world; objects: {', '.join(self.objects) or 'none'}"
            )
        return self.model.joint(name).id

    def object_body(self, name: str) -> int:
        """The body id of object ``name``; an unknown name lists the world's objects."""
        self._object_joint(name)
        return self.model.body(name).id

    def surface(self, name: str) -> Surface:
        """The support ``name`` ("table", "shelf"); an unknown name lists the world's surfaces."""
        if name not in self.surfaces:
            raise UnknownNameError(
                f"no surface {name!r} in the world; surfaces: {', '.join(self.surfaces) or 'none'}"
            )
        return self.surfaces[name]

    def object_pose(self, name: str) -> Pose:
        address = self.model.jnt_qposadr[self._object_joint(name)]
        return Pose(
            self.data.qpos[address : address + 3].copy(), self.data.qpos[address + 3 : address + 7].copy()
        )

    def object_speed(self, name: str) -> tuple[float, float]:
        """How fast object ``name`` moves now: its centre (m/s) and its turning (rad/s)."""
        dof = self.model.jnt_dofadr[self._object_joint(name)]
        velocity = self.data.qvel[dof : dof + 6]
        return float(np.linalg.norm(velocity[:3])), float(np.linalg.norm(velocity[3:]))

    def perceive(self, name: str) -> Pose:
        """Object ``name``'s pose as perception sees it now: exact, or with a fresh error of the run's
        :attr:`perception`."""
        pose = self.object_pose(name)
        return pose if self.perception is None else self.perception.look(pose, name)

    def perceived(self, name: str) -> Pose:
        """Object ``name``'s pose as the latest :meth:`perceive` saw it (its pose now if never perceived or
        perceived exactly)."""
        seen = None if self.perception is None else self.perception.last(name)
        return self.object_pose(name) if seen is None else seen

    def set_object_pose(self, name: str, position, quaternion=(1.0, 0.0, 0.0, 0.0)) -> None:
        """Places an object (at rest) and recomputes the derived quantities."""
        joint = self._object_joint(name)
        position = np.asarray(position, dtype=float)
        quaternion = np.asarray(quaternion, dtype=float)
        if (
            position.shape != (3,)
            or quaternion.shape != (4,)
            or not np.all(np.isfinite(np.r_[position, quaternion]))
        ):
            raise InputError(f"object pose must be 3 + 4 finite numbers, got {position!r}, {quaternion!r}")
        address, dof = self.model.jnt_qposadr[joint], self.model.jnt_dofadr[joint]
        self.data.qpos[address : address + 3] = position
        self.data.qpos[address + 3 : address + 7] = quaternion / np.linalg.norm(quaternion)
        self.data.qvel[dof : dof + 6] = 0.0
        mujoco.mj_forward(self.model, self.data)

    @checked(name=text("an object name"), surface=text("a surface name"), x=number, y=number, yaw=number)
    def place_on(self, name: str, surface: str, x: float, y: float, yaw: float = 0.0) -> None:
        """Sets an object upright on a surface at (x, y)."""
        self._object_joint(name)  # an unknown object is named
        support, item = self.surface(surface), self.objects[name]
        self.set_object_pose(
            name, [x, y, support.height + item.half_height], [np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
        )


def _add_object(spec: mujoco.MjSpec, item: GraspableObject, position) -> None:
    shapes = {"box": mujoco.mjtGeom.mjGEOM_BOX, "cylinder": mujoco.mjtGeom.mjGEOM_CYLINDER}
    if item.shape not in shapes:
        raise InputError(f"object {item.name!r}: shape must be one of {sorted(shapes)}, got {item.shape!r}")
    # Its mass and inertia given, not inferred from the geom: the robot model's compiler settings
    # (inertiagrouprange, inertiafromgeom) apply to everything compiled with it.
    body = spec.worldbody.add_body(name=item.name, pos=list(position))
    body.mass, body.inertia, body.ipos, body.explicitinertial = item.mass, list(item.inertia), [0, 0, 0], True
    body.add_freejoint(name=item.name)
    body.add_geom(
        name=item.name,
        type=shapes[item.shape],
        size=list(item.size) + [0.0] * (3 - len(item.size)),
        friction=list(item.friction),
        rgba=list(item.rgba),
        condim=4,
    )


def _add_surface(spec: mujoco.MjSpec, surface: Surface, base: float, rgba) -> None:
    centre = [sum(surface.x) / 2, sum(surface.y) / 2, (surface.height + base) / 2]
    half = [(surface.x[1] - surface.x[0]) / 2, (surface.y[1] - surface.y[0]) / 2, (surface.height - base) / 2]
    spec.worldbody.add_geom(
        name=surface.name,
        type=mujoco.mjtGeom.mjGEOM_BOX,
        pos=centre,
        size=half,
        rgba=rgba,
        friction=[0.7, 0.01, 0.0001],
    )


@checked(objects=items(instance(GraspableObject, "a GraspableObject"), "a tuple of objects"), robot=ROBOT)
def tabletop_world(objects: tuple[GraspableObject, ...] = (DEFAULT_BOX,), robot: str = "aila") -> World:
    """``robot`` at the origin facing +x, a table in front and a shelf board on the table's right side, where
    the robot's tabletop layout puts them.

    Objects start on the table, the first at the middle of the area the robot reaches, the others along y.
    The world integrates with MuJoCo's ``implicit`` integrator unless the robot's description names one.
    """
    description = robots.describe(robot)
    layout = description.tabletop
    if layout is None:
        raise InputError(f"robot {description.name!r} has no tabletop layout ({description.file}: tabletop)")
    table, shelf = Surface.of("table", layout.table), Surface.of("shelf", layout.shelf)
    spec = robots.build_spec(description)
    if "integrator" not in description.options:
        # A grasped object may spin between the pads, and implicitfast leaves out the Coriolis derivatives:
        # in exploratory grasps it diverged ("simulation is unstable") 9 times in 120, implicit 0 in 300.
        spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICIT
    table_top = 0.04  # thickness of the table plate; legs hold it up
    _add_surface(spec, table, table.height - table_top, [0.55, 0.4, 0.28, 1])
    for x in table.x:
        for y in table.y:
            inset = np.array([0.04 if x == table.x[0] else -0.04, 0.04 if y == table.y[0] else -0.04])
            spec.worldbody.add_geom(
                type=mujoco.mjtGeom.mjGEOM_BOX,
                pos=[x + inset[0], y + inset[1], (table.height - table_top) / 2],
                size=[0.025, 0.025, (table.height - table_top) / 2],
                rgba=[0.45, 0.32, 0.22, 1],
                contype=0,
                conaffinity=0,
            )
    _add_surface(spec, shelf, table.height, [0.35, 0.5, 0.65, 1])
    start = [sum(layout.reach[0]) / 2, sum(layout.reach[1]) / 2]
    for index, item in enumerate(objects):
        _add_object(spec, item, [start[0], start[1] + 0.15 * index, table.height + item.half_height])
    return World(description, spec, tuple(objects), (table, shelf), layout)


__getattr__ = old_names(__name__)  # the old names, for one release (besman.core.moved)
