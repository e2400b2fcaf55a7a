"""Graspable objects and the families tasks draw them from.

A :class:`GraspableObject` is one free rigid body (a box or a cylinder). An :class:`ObjectFamily` is a class
of them: its shapes, the ranges of their sizes, masses and frictions. A family is fitted to a gripper
(:meth:`ObjectFamily.for_gripper`): its widths are bounded by what the open fingers fit around with
:data:`FINGER_CLEARANCE` on each side, so that every arm gets objects it can hold.

An object's yaw is the direction of its x axis in the plane (rad). A box looks the same turned by 180 deg
(by 90 deg if its footprint is square) and a cylinder at any turn: :func:`yaw_symmetry` is that period, and
:func:`yaw_error` measures a yaw against a wanted one modulo it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from besman.core.errors import InputError

SHAPES = ("box", "cylinder")
FINGER_CLEARANCE = 0.005  # m the open fingers keep from the object on each side as they descend around it


@dataclass(frozen=True)
class GraspableObject:
    """A free rigid object.

    Attributes:
        name: body name (its geom and free joint are called the same).
        shape: "box" or "cylinder".
        size: MuJoCo geom size (box: half extents; cylinder: radius, half height) in m.
        mass: kg.
        friction: sliding, torsional, rolling friction coefficients.
        rgba: colour.
    """

    name: str
    shape: str = "box"
    size: tuple[float, ...] = (0.03, 0.03, 0.03)
    mass: float = 0.2
    friction: tuple[float, float, float] = (0.8, 0.01, 0.0001)
    rgba: tuple[float, float, float, float] = (0.85, 0.45, 0.15, 1.0)

    @property
    def half_height(self) -> float:
        return self.size[2] if self.shape == "box" else self.size[1]

    @property
    def footprint(self) -> tuple[float, float]:
        """Half extents in the plane along the object's x and y axes (a cylinder: its radius twice)."""
        return (self.size[0], self.size[1]) if self.shape == "box" else (self.size[0], self.size[0])

    @property
    def inertia(self) -> tuple[float, float, float]:
        """Principal moments of inertia (kg m^2) of the solid shape, about its centre."""
        if self.shape == "box":
            x, y, z = (2 * half for half in self.size)
            return tuple(self.mass * (a * a + b * b) / 12 for a, b in ((y, z), (x, z), (x, y)))
        radius, height = self.size[0], 2 * self.size[1]
        across = self.mass * (3 * radius * radius + height * height) / 12
        return (across, across, self.mass * radius * radius / 2)

    @property
    def narrowest(self) -> float:
        """The smallest width across which fingers can close on it (m)."""
        return 2 * min(self.footprint)


def yaw_symmetry(item: GraspableObject) -> float:
    """The turn (rad) after which ``item`` looks the same from above: pi for a box, pi / 2 for a box with a
    square footprint, 0 for a cylinder (any turn)."""
    if item.shape == "cylinder":
        return 0.0
    half_x, half_y = item.footprint
    return math.pi / 2 if math.isclose(half_x, half_y, rel_tol=0.0, abs_tol=1e-6) else math.pi


def yaw_error(yaw: float, wanted: float, item: GraspableObject) -> float:
    """How far (rad, >= 0) the yaw ``yaw`` is from ``wanted`` for ``item``, modulo its symmetry."""
    period = yaw_symmetry(item)
    if period == 0.0:
        return 0.0
    difference = (yaw - wanted) % period
    return float(min(difference, period - difference))


def yaw_of(rotation: np.ndarray) -> float:
    """The yaw (rad) of a body's x axis, from its 3 x 3 rotation matrix."""
    return float(math.atan2(rotation[1, 0], rotation[0, 0]))


@dataclass(frozen=True)
class ObjectFamily:
    """A class of graspable objects: its ``shapes`` and the ranges (low, high) of their ``width`` (a box's
    width and depth, a cylinder's diameter), ``height`` (m), ``mass`` (kg) and sliding ``friction``."""

    shapes: tuple[str, ...] = SHAPES
    width: tuple[float, float] = (0.04, 0.07)
    height: tuple[float, float] = (0.05, 0.08)
    mass: tuple[float, float] = (0.1, 0.3)
    friction: tuple[float, float] = (0.7, 1.0)

    def for_gripper(self, aperture: float, robot: str) -> ObjectFamily:
        """The family with its widths bounded by a gripper opening ``aperture`` (m between the pads): every
        object of it fits between the open fingers with :data:`FINGER_CLEARANCE` on each side. An aperture
        too small for the family's narrowest object is refused with both numbers."""
        widest = aperture - 2 * FINGER_CLEARANCE
        if widest < self.width[0]:
            raise InputError(
                f"robot {robot!r}: its gripper opens {aperture * 100:.1f} cm, so it holds objects up to "
                f"{widest * 100:.1f} cm wide ({FINGER_CLEARANCE * 100:.1f} cm clearance on each side); the "
                f"task's narrowest object is {self.width[0] * 100:.1f} cm wide"
            )
        return replace(self, width=(self.width[0], min(self.width[1], widest)))

    def make(
        self,
        name: str,
        shape: str,
        size,
        mass: float,
        friction: float,
        rgba: tuple[float, float, float, float] = (0.85, 0.45, 0.15, 1.0),
    ) -> GraspableObject:
        """An object of the family: ``shape`` with ``size`` = (width, depth, height) in m (a cylinder's
        diameter is its width; its depth is not used)."""
        if shape not in self.shapes:
            raise InputError(f"object shape must be one of {', '.join(self.shapes)}, got {shape!r}")
        width, depth, height = (float(v) for v in size)
        half = (width / 2, depth / 2, height / 2) if shape == "box" else (width / 2, height / 2)
        return GraspableObject(name, shape, half, float(mass), (float(friction), 0.01, 0.0001), rgba)
