"""The demo gallery: manipulation demos, each a tree file in ``examples/trees`` and the world it needs.

A :class:`Demo` names its tree file and prepares a run of it for a seed: the world with the robot and
objects the tree needs, the values on the blackboard (``/task/...``), whatever happens to the run that the
robot does not plan (a :mod:`disturbance <besman.sim.disturbances>`), and how its outcome is judged
(``success`` in the summary, measured in the simulation, not taken from the tree's own status alone). The
same seed gives the same configuration and the same run. ``besman demo --list`` lists :data:`DEMOS`;
``besman demo NAME [--seed N] [--view]`` runs one.

- ``grasp-then-place``: the robot (AILA by default; ``--robot NAME``) takes the box from the table to the
  shelf (without a seed: :data:`DEFAULT_CONFIGURATION` on AILA, the middle of the layout's areas elsewhere).
- ``sort``: three boxes, each to its own place on the shelf, in a loop over the blackboard's list of objects
  (:class:`~besman.trees.loops.ForEach`); one box is taken out of the hand during its carry and set down
  elsewhere on the table, and the tree grasps it again. Any robot with a tabletop layout.
- ``handover``: a two-arm robot's (AILA by default; ``--robot openarm``) left arm picks a bar from the
  table's left side at one end while the right arm gets ready (in parallel), presents it in front of the body
  (where: the robot's layout, ``tabletop.handover``), the right hand takes the other end (both grippers
  closed), the left lets go, rises and goes home, then the right arm puts the bar on the shelf;
  ``KeepApart`` guards the moves, and the run counts the ticks at which the arms touch in the simulation
  (none is a success condition).
- ``throw``: the PA-10 throws the ball at a target (``--target X,Y``, or drawn from the template's box) with
  the throwing skill template of the paper's experiment.

The tree files ship with the package (:mod:`besman.examples`), beside the pools they name.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import py_trees

import besman.robots as robots
from besman import examples
from besman.robots.robot import ROBOT
from besman.sim.disturbances import TakeFromHand
from besman.sim.executor import Executor
from besman.sim.pick_place import PLACE_TOLERANCE
from besman.sim.proximity import ArmProximity, moved_geoms
from besman.sim.tasks import one_hand_tabletop
from besman.sim.world import GraspableObject, tabletop_world
from besman.skills.errors import InputError
from besman.skills.validation import CALLABLE, PATH, SEED, checked, mapping, numeric, optional, text
from besman.trees.blackboard import set_task_values
from besman.trees.files import load_tree
from besman.trees.runner import Runner, RunResult
from besman.trees.summary import Measured, RunSummary
from besman.trees.tabletop import MEASUREMENTS as TABLETOP_MEASUREMENTS
from besman.trees.tabletop import measure as measure_tabletop
from besman.trees.tabletop import tabletop_run

EXAMPLES = examples.path("trees")
DEFAULT_CONFIGURATION = {"object": (0.55, -0.08), "place": (0.54, -0.41)}  # the docs' examples use it too
THROW_TOLERANCE = 0.5  # m: a throw demo is done when the ball lands this close to its target
Observer = Callable[[Runner, dict], None]


@dataclass(frozen=True)
class DemoRun:
    """A prepared run: the runner (not started; its configuration is in ``runner.run_info``) and what the
    demo measures in the simulation once the run has ended."""

    runner: Runner
    measure: Callable[[], Measured]

    def judge(self, result: RunResult) -> RunSummary:
        """The summary of the run that ended with ``result``."""
        return RunSummary.of(self.runner, result, self.measure())


@dataclass(frozen=True)
class Demo:
    """A demo of the gallery: its name, one line on what it shows, its tree file, how a run is prepared
    (``prepare(seed, options, observe)``; ``options["robot"]`` names the robot), the robots it runs on by
    default, which robots can run it (``fits(robot description)``) and what its summary measures (name:
    meaning, the keys of :attr:`RunSummary.measurements <besman.trees.summary.RunSummary.measurements>`)."""

    name: str
    title: str
    tree: str
    prepare: Callable[[int | None, Mapping, Observer | None], DemoRun]
    robot: str
    fits: Callable[[robots.RobotDescription], bool]
    measurements: Mapping[str, str]

    @property
    def path(self) -> Path:
        return EXAMPLES / self.tree

    def check_robot(self, robot: str | None) -> str:
        """``robot`` (default: the demo's own) if the demo runs on it; otherwise an error naming the robots
        it runs on, before any work."""
        return robots.choose(robot, self.robot, self.fits, f"demo {self.name}")


def _two_hand_tabletop(robot: robots.RobotDescription) -> bool:
    """A tabletop layout with a handover and two arms "right" and "left", each with a gripper."""
    arms = robot.arms
    return (
        robot.tabletop is not None
        and robot.tabletop.handover is not None
        and all(side in arms and arms[side].gripper is not None for side in ("right", "left"))
    )


def observers(*calls: Observer | None) -> Observer | None:
    """One runner observer that calls the given ones in turn (None if none is given)."""
    calls = [call for call in calls if call is not None]
    if len(calls) <= 1:
        return calls[0] if calls else None

    def observe(runner: Runner, record: dict) -> None:
        for call in calls:
            call(runner, record)

    return observe


def _runner(
    demo: str,
    root,
    executor: Executor,
    seed: int | None,
    settings: dict,
    max_sim_time: float,
    observe,
    **more,
) -> Runner:
    """A demo's runner, its log header naming the demo, seed and settings (and ``more``: its options), which
    is what a replay needs to rebuild the demo's world."""
    run_info = {
        "tree": str(EXAMPLES / DEMOS[demo].tree),
        "demo": demo,
        "seed": seed,
        **more,
        "settings": settings,
    }
    return Runner(root, executor, max_sim_time=max_sim_time, run_info=run_info, observe=observe)


# -- grasp-then-place --------------------------------------------------------------------------------------


def _middle(area) -> tuple[float, float]:
    (x0, x1), (y0, y1) = area
    return round((x0 + x1) / 2, 4), round((y0 + y1) / 2, 4)


def grasp_then_place_values(robot: str, seed: int | None) -> dict[str, tuple[float, float]]:
    """The object and place of grasp-then-place without a seed: the default ones on AILA, the middle of the
    layout's object and place areas on other robots (with a seed: none, they are drawn)."""
    if seed is not None:
        return {}
    if robot == "aila":
        return dict(DEFAULT_CONFIGURATION)
    layout = robots.describe(robot).tabletop
    return {"object": _middle(layout.objects), "place": _middle(layout.places)}


def _grasp_then_place(seed: int | None, options: Mapping, observe: Observer | None) -> DemoRun:
    robot = options["robot"]
    values = grasp_then_place_values(robot, seed)
    runner, _ = tabletop_run(EXAMPLES / "grasp_then_place.yaml", values, seed=seed, robot=robot)
    runner.observe = observe
    runner.run_info["demo"] = "grasp-then-place"
    return DemoRun(runner, lambda: measure_tabletop(runner))


# -- sort --------------------------------------------------------------------------------------------------

SORT_OBJECTS = (
    GraspableObject("red", rgba=(0.80, 0.15, 0.12, 1.0)),
    GraspableObject("green", rgba=(0.20, 0.62, 0.25, 1.0)),
    GraspableObject("blue", rgba=(0.15, 0.35, 0.80, 1.0)),
)
# Each box's own place on the shelf, from the middle of the layout's place area, 14-15 cm apart (the open
# hand spans 9 cm, plus the fingers). The carried box clears the shelf by 6 cm, as high as a box that
# stands there, so the far place is filled first and no carry passes over a placed box. (On AILA:
# blue (0.52, -0.50), red (0.45, -0.37), green (0.60, -0.37).)
SORT_OFFSETS = {"blue": (-0.015, -0.09), "red": (-0.085, 0.04), "green": (0.065, 0.04)}
# Where the boxes stand, from the layout's object area: 2 cm farther and 1 cm more to the right (on AILA:
# x, y from (0.47, -0.16) to (0.64, 0.0), the right arm's top-down grasps from its home pose).
SORT_AREA_SHIFT = ((0.02, 0.02), (-0.01, 0.0))
SORT_SPACING = 0.12  # m between the boxes on the table: the open fingers keep clear of the neighbours


def sort_places(robot: str) -> dict[str, tuple[float, float]]:
    """Each sorted box's place on ``robot``'s shelf."""
    x, y = _middle(robots.describe(robot).tabletop.places)
    return {name: (round(x + dx, 4), round(y + dy, 4)) for name, (dx, dy) in SORT_OFFSETS.items()}


def _free_spots(rng: np.random.Generator, robot: str, count: int, taken=()) -> list[tuple[float, float]]:
    """``count`` spots on ``robot``'s table (its object area shifted by :data:`SORT_AREA_SHIFT`), each
    :data:`SORT_SPACING` from the others and from ``taken``."""
    (x0, x1), (y0, y1) = robots.describe(robot).tabletop.objects
    (dx0, dx1), (dy0, dy1) = SORT_AREA_SHIFT
    low, high = (x0 + dx0, y0 + dy0), (x1 + dx1, y1 + dy1)
    taken = [np.asarray(spot) for spot in taken]
    for _ in range(10_000):  # all at once, so that early spots cannot leave no room for later ones
        spots = rng.uniform(low, high, size=(count, 2))
        together = [*taken, *spots]
        gaps = [np.linalg.norm(a - b) for i, a in enumerate(together) for b in together[i + 1 :]]
        if min(gaps, default=np.inf) >= SORT_SPACING:
            return [(round(float(x), 4), round(float(y), 4)) for x, y in spots]
    raise AssertionError("no room on the table for the boxes")  # the ranges leave room: not reached


def _sort(seed: int | None, options: Mapping, observe: Observer | None) -> DemoRun:
    robot = options["robot"]
    places = sort_places(robot)
    rng = np.random.default_rng(seed)
    names = [item.name for item in SORT_OBJECTS]
    spots = dict(zip(names, _free_spots(rng, robot, len(names)), strict=True))
    order = sorted(names, key=lambda name: places[name][1])  # the far places first
    slipping = order[int(rng.integers(len(order)))]
    # It is set down clear of the boxes still on the table then (those after it in the loop).
    waiting = [spots[name] for name in order[order.index(slipping) + 1 :]]
    slip = TakeFromHand(slipping, _free_spots(rng, robot, 1, waiting)[0], after=float(rng.uniform(0.3, 0.9)))
    items = [{"object": name, "target": list(places[name])} for name in order]
    py_trees.blackboard.Blackboard.clear()
    root = load_tree(EXAMPLES / "sort.yaml")
    world = tabletop_world(SORT_OBJECTS, robot)
    for name, (x, y) in spots.items():
        world.place_on(name, "table", x, y)
    set_task_values({"objects": items})
    settings = {
        "objects": spots,
        "places": {name: list(places[name]) for name in order},
        "slip": {"object": slip.object, "after_s": round(slip.after, 3), "set_down_at": list(slip.where)},
    }

    runner = _runner(
        "sort",
        root,
        Executor(world),
        seed,
        settings,
        240.0,
        observers(lambda runner, _: slip(runner.executor), observe),
        robot=robot,
    )

    def measure() -> Measured:
        errors = {
            name: float(np.linalg.norm(world.object_pose(name).position[:2] - places[name])) for name in names
        }
        shown = ", ".join(f"{name} {error * 100:.1f} cm" for name, error in errors.items())
        slipped = slip.object if slip.done else None
        return Measured(
            max(errors.values()) <= PLACE_TOLERANCE and slip.done,
            f"placement errors {shown}; {slipped or 'no box'} slipped and was grasped again",
            {
                "placement_errors_m": {name: round(error, 4) for name, error in errors.items()},
                "slipped": slipped,
            },
        )

    return DemoRun(runner, measure)


# -- handover ----------------------------------------------------------------------------------------------

# A bar, so that two hands can hold it at once from above, 12 cm apart: 26 x 4 x 4 cm, lying along y.
BAR = GraspableObject("bar", size=(0.02, 0.13, 0.02), mass=0.2, rgba=(0.85, 0.65, 0.15, 1.0))


class ArmContacts:
    """An observer of two arms, every tick: the ticks at which they touch (a contact between their collision
    geoms in the simulation) and the closest they came (MuJoCo's geom distance, searched up to 0.5 m)."""

    def __init__(self, first: Executor, second: Executor) -> None:
        self.world = first.world
        self.first, self.second = np.array(moved_geoms(first)), np.array(moved_geoms(second))
        self.proximity = ArmProximity(first, second)
        self.touching = 0
        self.closest = 0.5

    def __call__(self, runner: Runner, record: dict) -> None:
        data = self.world.data
        geoms = data.contact.geom[: data.ncon]
        one = np.isin(geoms[:, 0], self.first) & np.isin(geoms[:, 1], self.second)
        other = np.isin(geoms[:, 1], self.first) & np.isin(geoms[:, 0], self.second)
        self.touching += bool((one | other).any())
        self.closest = min(self.closest, self.proximity.distance(self.closest))


def _draw(rng: np.random.Generator, area) -> np.ndarray:
    """A point of an (x range, y range) area."""
    (x0, x1), (y0, y1) = area
    return rng.uniform((x0, y0), (x1, y1)).round(4)


def _handover(seed: int | None, options: Mapping, observe: Observer | None) -> DemoRun:
    layout = robots.describe(options["robot"]).tabletop.handover
    rng = np.random.default_rng(seed)
    bar = _draw(rng, layout.bar)
    place = _draw(rng, layout.places)
    py_trees.blackboard.Blackboard.clear()
    root = load_tree(EXAMPLES / "handover.yaml")
    world = tabletop_world((BAR,), options["robot"])
    world.place_on("bar", "table", *bar)
    # Both arms at once: the waist they share is held (a turning torso would carry the left hand, and the
    # bar, with it).
    right = Executor(world, ("right", "left"))
    contacts = ArmContacts(right, right.arm_executor("left"))
    poses = {"ready": asdict(layout.ready), "present": asdict(layout.present)}
    set_task_values({"place": place, **poses})
    settings = {"bar": bar.tolist(), "place": place.tolist()}

    runner = _runner(
        "handover", root, right, seed, settings, 120.0, observers(contacts, observe), robot=options["robot"]
    )

    def measure() -> Measured:
        error = float(np.linalg.norm(world.object_pose("bar").position[:2] - place))
        return Measured(
            error <= PLACE_TOLERANCE and contacts.touching == 0,
            f"placement error {error * 100:.1f} cm; the arms came within {contacts.closest * 100:.1f} cm "
            f"and touched at {contacts.touching} ticks",
            {
                "placement_error_m": round(error, 4),
                "ticks_arms_touching": contacts.touching,
                "arms_closest_m": round(contacts.closest, 4),
            },
        )

    return DemoRun(runner, measure)


# -- throw -------------------------------------------------------------------------------------------------


def _throw(seed: int | None, options: Mapping, observe: Observer | None) -> DemoRun:
    from besman.sim.throw_execution import ThrowingExecutor
    from besman.sim.throwing import ThrowingTask

    task = ThrowingTask(variant="paper")
    target = options.get("target")
    if target is None:
        target = np.random.default_rng(seed).uniform(task.bounds.low, task.bounds.high).round(3)
    target = np.asarray(target, dtype=float)
    if target.shape != (2,):
        raise InputError(f"--target needs two numbers, X,Y, got {target.tolist()}")
    try:
        task.bounds.check(target)  # outside the template's box: refused by name, before any work
    except ValueError as error:
        raise InputError(f"--target {target.tolist()}: {error}") from None
    py_trees.blackboard.Blackboard.clear()
    root = load_tree(EXAMPLES / "throw.yaml")
    executor = ThrowingExecutor(task)
    executor.wind_up()
    set_task_values({"target": target})
    settings = {"target": target.tolist()}
    runner = _runner(
        "throw",
        root,
        executor,
        seed,
        settings,
        10.0,
        observe,
        robot=options["robot"],
        options={"target": target.tolist()},
    )

    def measure() -> Measured:
        flight = executor.throw
        landing = None if flight is None or flight.landing is None else np.round(flight.landing, 3)
        miss = None if landing is None else float(np.linalg.norm(flight.landing - target))
        return Measured(
            miss is not None and miss <= THROW_TOLERANCE,
            "no landing"
            if landing is None
            else f"landed at {landing.tolist()}, {miss:.3f} m from {target.tolist()}",
            {
                "target": target.tolist(),
                "landing": None if landing is None else landing.tolist(),
                "miss_m": None if miss is None else round(miss, 3),
            },
        )

    return DemoRun(runner, measure)


DEMOS: dict[str, Demo] = {
    demo.name: demo
    for demo in (
        Demo(
            "grasp-then-place",
            "the robot takes the box from the table and puts it on the shelf (--robot NAME)",
            "grasp_then_place.yaml",
            _grasp_then_place,
            "aila",
            one_hand_tabletop,
            TABLETOP_MEASUREMENTS,
        ),
        Demo(
            "sort",
            "three boxes, each to its own place on the shelf, in a loop over the objects; one slips and is "
            "grasped again (--robot NAME)",
            "sort.yaml",
            _sort,
            "aila",
            one_hand_tabletop,
            {
                "placement_errors_m": "each box's distance from its own place on the shelf, by box",
                "slipped": "the box taken out of the hand during its carry (None if the slip never came)",
            },
        ),
        Demo(
            "handover",
            "a two-arm robot's left arm picks a bar and hands it to the right arm, which puts it on the "
            "shelf",
            "handover.yaml",
            _handover,
            "aila",
            _two_hand_tabletop,
            {
                "placement_error_m": "the bar's distance from its place on the shelf, in the plane",
                "ticks_arms_touching": "ticks at which the two arms touched in the simulation (done: none)",
                "arms_closest_m": "the closest the arms came (searched up to 0.5 m)",
            },
        ),
        Demo(
            "throw",
            "the PA-10 throws the ball at a target with the throwing skill template (--target X,Y)",
            "throw.yaml",
            _throw,
            "pa10",
            lambda robot: robot.name == "pa10",
            {
                "target": "where the ball should land, x, y on the floor",
                "landing": "where it first touched the floor (None if it never did)",
                "miss_m": "the distance between the two (done: within 0.5 m)",
            },
        ),
    )
}


def demo(name: str) -> Demo:
    """The demo called ``name``; an :class:`~besman.skills.errors.InputError` lists the others."""
    if name not in DEMOS:
        raise InputError(f"no demo {name!r}; demos: {', '.join(DEMOS)}")
    found = DEMOS[name]
    if not found.path.is_file():
        raise InputError(f"demo {name}: its tree {found.path} is missing from the installed package")
    return found


# A demo's arguments, checked where run_demo or prepare_demo is called: its options are these alone.
DEMO_ARGUMENTS = {
    "name": text("a demo name"),
    "seed": optional(SEED),
    "options": mapping(robot=optional(ROBOT), target=optional(numeric)),
    "observe": optional(CALLABLE),
}


@checked(**DEMO_ARGUMENTS, log=optional(PATH))
def run_demo(
    name: str,
    seed: int | None = None,
    options: Mapping | None = None,
    *,
    log: str | Path | None = None,
    observe: Observer | None = None,
) -> RunSummary:
    """Runs a demo and returns its summary; ``options["robot"]`` chooses the robot (default: the demo's)."""
    prepared = prepare_demo(name, seed, options, observe)
    return prepared.judge(prepared.runner.run(log=log))


@checked(**DEMO_ARGUMENTS)
def prepare_demo(
    name: str, seed: int | None = None, options: Mapping | None = None, observe: Observer | None = None
) -> DemoRun:
    """A demo's prepared run, its robot (``options["robot"]``, default the demo's) checked first: a robot
    the demo does not fit is refused by name, before any work."""
    found = demo(name)
    options = dict(options or {})
    options["robot"] = found.check_robot(options.get("robot"))
    return found.prepare(seed, options, observe)
