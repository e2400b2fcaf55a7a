"""Pick and place's one success rule, as a run's measurements: where the released box came to rest
(:func:`~besman.sim.outcomes.placement`: upright on the shelf within 2 cm of the target and 5 deg of its yaw
after settling), and
for the pick alone whether the box is in the hand and up (:func:`~besman.sim.outcomes.lifted`).

The same predicates judge the task's scripted episodes (:mod:`besman.tasks.pick_place.episode`) and the
rewards of its learned blocks (:mod:`besman.sim.block_simulation`), so all of them judge a final state alike.
"""

from __future__ import annotations

import math

from besman.sim.outcomes import lifted, placement
from besman.sim.world import World
from besman.trees.summary import Measured


def measure_placement(world: World, name: str, place) -> Measured:
    """:func:`placement` against ``place`` (x, y and the yaw in deg) as a run's measurements."""
    placed = placement(world, name, place[:2], yaw=math.radians(place[2]))
    return Measured(
        placed.success,
        f"placement error {placed.error * 100:.1f} cm, {placed.yaw_error_degrees:.1f} deg"
        + ("" if placed.success else f" ({placed.message})"),
        {
            "placement_error_m": round(placed.error, 4),
            "placement_yaw_error_deg": round(placed.yaw_error_degrees, 2),
            "tilt_deg": round(placed.tilt_degrees, 2),
            "box_position": list(placed.position),
        },
    )


def measure_lift(executor, name: str) -> Measured:
    """:func:`lifted` as a run's measurements."""
    world = executor.world
    position = world.object_pose(name).position
    rise = float(position[2] - world.surface("table").height - world.objects[name].half_height)
    held = bool(executor.hand.holds(name))
    done = lifted(world, executor.hand, name)
    return Measured(
        done,
        f"the box {'is' if held else 'is not'} in the hand, {rise * 100:.1f} cm above the table",
        {"lift_m": round(rise, 4), "held": held, "box_position": [round(float(v), 4) for v in position]},
    )
