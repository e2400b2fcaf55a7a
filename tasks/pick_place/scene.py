"""Pick and place's scene: the object family and the object a run places, the areas each robot's first arm
works in (its table area and its place area on the shelf), and the task values that place them."""

from __future__ import annotations

import numpy as np

from besman.core.errors import InputError
from besman.core.seeds import child_seed
from besman.sim.objects import FINGER_CLEARANCE, GraspableObject, ObjectFamily
from besman.sim.perturbations import Perturbations
from besman.tasks.base import TaskValue

# The place area on the shelf board per robot, x and y ranges (m): where its first arm reaches top-down
# placings and the poses above them (each robot's README says how it was found: AILA's is where the right
# arm, turning the waist, keeps every joint 5 % of its range from its limits for some yaw, on a grid).
PLACES = {
    "aila": ((0.45, 0.62), (-0.48, -0.34)),
    "ur5e": ((0.32, 0.49), (-0.45, -0.31)),
    "openarm": ((0.17, 0.30), (-0.42, -0.32)),
}
DEFAULT_CONFIGURATION = {"aila": {"object": (0.55, -0.08, 0.0), "place": (0.54, -0.41, 0.0)}}
FAMILY = ObjectFamily()  # boxes and cylinders 4-7 cm wide, 5-8 cm high, 0.1-0.3 kg, friction 0.7-1.0
DEFAULT_OBJECT = {"shape": (0,), "size": (0.06, 0.06, 0.06)}  # the 6 cm box, clipped to what fits


def _pose(name: str, description: str, surface: str, target: bool = False) -> TaskValue:
    """A task value that places something on a surface: x and y (m) and its yaw (deg)."""
    columns = tuple(f"{name}_{column}" for column in ("x", "y", "yaw"))
    return TaskValue(name, columns, ("m", "m", "deg"), description, surface=surface, target=target)


OBJECT = _pose("object", "where the object stands on the table, and its yaw", "table")
PLACE = _pose(
    "place", "where the object goes on the shelf, and the yaw it should stand at", "shelf", target=True
)
SHAPE = TaskValue("shape", ("shape",), "", "the object's shape", whole=True, choices=FAMILY.shapes)
SIZE = TaskValue(
    "size",
    ("object_width", "object_depth", "object_height"),
    "m",
    "the object's width, depth and height (a cylinder: diameter, diameter, height)",
)
YAWS = (-180.0, 180.0)  # deg: the whole circle
# The object's pose perceived up to 1.5 cm and 5 deg off; pushed 1-3 cm half-way through the reach.
PERTURBATIONS = Perturbations(position=0.015, yaw=5.0, push=0.03, smallest_push=0.01, during="reach")
PROPERTIES_STREAM = 1  # the child of the run's seed that draws the object's mass and friction


def _read_places(section: dict, where: str, layout):
    from besman.robots.fields import DescriptionError
    from besman.robots.tabletop import read_area

    if "places" not in section:
        raise DescriptionError(f"{where}: missing 'places' (the place area on the shelf, x and y ranges)")
    return read_area(section["places"], f"{where}.places", None if layout is None else layout.shelf)


def areas(robot: str):
    """The object area (table) and the place area (shelf) on ``robot``, or None where it has no place area
    (not a robot of :data:`PLACES`, and no ``tasks.pick-place.places`` in its description)."""
    import besman.robots as robots
    from besman.tasks import task

    layout = robots.describe(robot).tabletop
    places = task("pick-place").robot_numbers(robot, PLACES, _read_places)
    if layout is None or places is None:
        return None
    return layout.reach, places


def aperture(robot: str) -> float:
    """How far (m) the pads of ``robot``'s first gripper are apart, open to grasp."""
    import besman.robots as robots

    return 2 * next(iter(robots.describe(robot).arms.values())).gripper.open


def family(robot: str) -> ObjectFamily:
    """:data:`FAMILY` as ``robot``'s first gripper holds it; a gripper too small for any of it is refused
    with both numbers."""
    return FAMILY.for_gripper(aperture(robot), robot)


def check_holdable(robot: str, size: np.ndarray, shape: np.ndarray) -> None:
    """An object of ``size`` (width, depth, height) and ``shape`` fits in the robot's open gripper, or an
    error gives both widths."""
    if len(size) != 3 or len(shape) != 1:
        return  # the count is refused by resolve, with the names
    cylinder = FAMILY.shapes[int(shape[0]) % len(FAMILY.shapes)] == "cylinder"
    narrowest = float(size[0] if cylinder else min(size[0], size[1]))
    needed, opening = narrowest + 2 * FINGER_CLEARANCE, aperture(robot)
    if needed > opening + 1e-9:
        raise InputError(
            f"--set size: the object is {narrowest * 100:.1f} cm across its narrowest side and needs an "
            f"opening of {needed * 100:.1f} cm ({FINGER_CLEARANCE * 100:.1f} cm clearance on each side); "
            f"robot {robot!r}'s gripper opens {opening * 100:.1f} cm"
        )


def the_object(robot: str, values, seed: int | None) -> GraspableObject:
    """The task's object (the world's ``box``) for its ``shape`` and ``size`` values, its mass and friction
    drawn with ``seed`` from the family's ranges (without one: their middles)."""
    objects = family(robot)
    if seed is None:
        mass, friction = (sum(objects.mass) / 2, sum(objects.friction) / 2)
    else:
        rng = np.random.default_rng(child_seed(seed, PROPERTIES_STREAM))
        mass, friction = rng.uniform(*objects.mass), rng.uniform(*objects.friction)
    shape = objects.shapes[int(values["shape"][0])]
    return objects.make("box", shape, values["size"], mass, friction)


def first_hand(robot) -> bool:
    """Whether the robot's first arm has a gripper (the hand the one-handed tasks use)."""
    arms = list(robot.arms.values())
    return bool(arms) and arms[0].gripper is not None


def one_hand_tabletop(robot) -> bool:
    """A work surface, a first arm with a gripper and a place area: what pick and place needs."""
    return first_hand(robot) and areas(str(robot.folder)) is not None
