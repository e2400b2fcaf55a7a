"""Perturbations: how a run differs from the one the robot expects, drawn with the run's seed.

A skill that works only when perception is exact and nothing moves is not robust. A task declares its
:class:`Perturbations` (pick and place: the object's pose perceived up to 1.5 cm and 5 deg off, the object
pushed by up to 3 cm while the hand approaches it); a run with ``perturb`` set draws them from its seed:

- ``"perception"``: every look at the object (:meth:`~besman.sim.world.World.perceive`, each try of a
  grasp) is off by a fresh error, uniform in a disc of :attr:`Perturbations.position` in the plane and
  within :attr:`Perturbations.yaw` about the vertical. The planners see only what was perceived.
- ``"push"``: the same, and the object is pushed (:class:`PushObject`) once, part way through the motion
  :attr:`Perturbations.during`, by a distance drawn between :attr:`Perturbations.smallest_push` and
  :attr:`Perturbations.push` in a direction drawn over the circle. Nothing tells the robot; only a retry
  that perceives again finds the object where it now stands.

The object's mass and friction are drawn from its family's ranges by the seed of every seeded run already
(:func:`~besman.tasks.pick_place.the_object`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from besman.core.errors import InputError

if TYPE_CHECKING:  # tasks declare their perturbations at import, which must stay light
    from besman.robots.kinematics import Pose

MODES = ("perception", "push")
# m a pushed object may overlap what it touches (its support, at rest, a fraction of a millimetre), and the
# shares of the shift tried in turn (the first free one is taken).
PUSH_OVERLAP = 0.002
PUSH_SHARES = (1.0, 0.5, 0.25)


def check_mode(perturb: str | None) -> None:
    if perturb is not None and perturb not in MODES:
        raise InputError(f"perturb must be one of {', '.join(MODES)}, got {perturb!r}")


@dataclass(frozen=True)
class Perturbations:
    """A task's perturbation model (see the module documentation): perception errors of ``position`` (m)
    and ``yaw`` (deg) at most, and a push between ``smallest_push`` and ``push`` (m) ``push_at`` of the
    way through the motion named ``during``."""

    position: float = 0.015
    yaw: float = 5.0
    push: float = 0.03
    smallest_push: float = 0.01
    during: str = "reach"
    push_at: float = 0.5

    def perception(self, rng: np.random.Generator) -> Perception:
        return Perception(self.position, np.radians(self.yaw), rng)

    def push_of(self, name: str, rng: np.random.Generator) -> PushObject:
        """The push of object ``name``, its distance and direction drawn with ``rng``."""
        distance = rng.uniform(self.smallest_push, self.push)
        angle = rng.uniform(-np.pi, np.pi)
        shift = distance * np.array([np.cos(angle), np.sin(angle)])
        return PushObject(name, (float(shift[0]), float(shift[1])), self.during, self.push_at)

    def describe(self) -> dict:
        return {
            "perception_position_m": self.position,
            "perception_yaw_deg": self.yaw,
            "push_m": [self.smallest_push, self.push],
            "push_during": self.during,
            "push_at": self.push_at,
        }


@dataclass
class Perception:
    """An imperfect sensor of objects' poses: each :meth:`look` is off by a fresh error (uniform in a disc of
    ``position`` m, within ``yaw`` rad); :meth:`last` is what the latest look saw."""

    position: float
    yaw: float
    rng: np.random.Generator
    seen: dict[str, Pose] = field(default_factory=dict)

    def look(self, pose: Pose, name: str) -> Pose:
        radius = self.position * np.sqrt(self.rng.uniform())  # uniform over the disc's area
        angle = self.rng.uniform(-np.pi, np.pi)
        turn = self.rng.uniform(-self.yaw, self.yaw)
        offset = radius * np.array([np.cos(angle), np.sin(angle), 0.0])
        self.seen[name] = type(pose)(pose.position + offset, _turned_about_z(pose.quaternion, turn))
        return self.seen[name]

    def last(self, name: str) -> Pose | None:
        return self.seen.get(name)


def _turned_about_z(quaternion: np.ndarray, angle: float) -> np.ndarray:
    """The unit quaternion (w, x, y, z) ``quaternion`` turned by ``angle`` (rad) about the world's vertical:
    the product (cos a/2, 0, 0, sin a/2) * q."""
    c, s = np.cos(angle / 2), np.sin(angle / 2)
    w, x, y, z = quaternion
    return np.array([c * w - s * z, c * x - s * y, c * y + s * x, c * z + s * w])


@dataclass
class PushObject:
    """Pushes ``object`` by ``shift`` (x, y in m) on the table once, when the motion named ``during`` has run
    ``at`` of its planned duration. Call it after every control cycle or tick with the executor.

    The object is moved as a hand would push it: only to where it overlaps nothing (no contact deeper than
    :data:`PUSH_OVERLAP`), so the whole shift, or else half or a quarter of it in the same direction; where
    none is free (a finger in the way), it stays and the push counts as ``blocked``. Moved into a finger, the
    contact's force would throw it out of the simulation (MuJoCo's "simulation is unstable")."""

    object: str
    shift: tuple[float, float]
    during: str = "reach"
    at: float = 0.5
    done: bool = False
    blocked: bool = False

    def __call__(self, executor) -> bool:
        """Whether it pushed now."""
        motion = executor.motion
        if self.done or motion is None or motion.name != self.during:
            return False
        dmp = getattr(getattr(motion, "primitive", None), "dmp", None)
        if dmp is None or motion.cycles * executor.config.control_period < self.at * dmp.execution_time:
            return False
        self.done = True
        self.blocked = push_free(executor.world, self.object, self.shift) == 0.0
        return not self.blocked

    def describe(self) -> dict:
        return {
            "object": self.object,
            "shift_m": [round(v, 4) for v in self.shift],
            "done": self.done,
            "blocked": self.blocked,
        }


def push_free(world, name: str, shift) -> float:
    """Moves object ``name`` by the first share of ``shift`` (x, y in m) in :data:`PUSH_SHARES` where it
    overlaps nothing deeper than :data:`PUSH_OVERLAP`, and returns the share; where none is free it stays
    as it was (its speed too) and the share is 0."""
    import mujoco  # here: listing the tasks imports this module, and must not bring MuJoCo

    pose, body = world.object_pose(name), world.object_body(name)
    velocity = world.data.qvel.copy()
    for share in PUSH_SHARES:
        world.set_object_pose(name, pose.position + share * np.r_[shift, 0.0], pose.quaternion)
        if _deepest_contact(world, body) <= PUSH_OVERLAP:
            return share
    world.set_object_pose(name, pose.position, pose.quaternion)
    world.data.qvel[:] = velocity
    mujoco.mj_forward(world.model, world.data)
    return 0.0


def _deepest_contact(world, body: int) -> float:
    """How deep (m) the deepest contact of ``body``'s geoms overlaps (0 without one)."""
    contacts = world.data.contact
    mine = (world.model.geom_bodyid[contacts.geom] == body).any(axis=1)
    return max(0.0, -float(contacts.dist[mine].min())) if mine.any() else 0.0
