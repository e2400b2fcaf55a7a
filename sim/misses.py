"""Why a top-down plan could not be made.

A planner tries candidates (hand yaws, heights) and each check a candidate fails leaves a :class:`Miss`.
When none passes, :meth:`Misses.error` names the candidate that came nearest, the check it failed with its
numbers, and what in the robot's description (its file and field) or the task would change it: an arm
brought by a user fails for a reason the user can act on, not "no grasp".
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from besman.core.errors import BesmanError


class PlanningError(BesmanError):
    """No motion satisfies the plan's conditions; the message says which check failed and what to change."""


@dataclass(frozen=True)
class Miss:
    """One check that one candidate failed.

    Attributes:
        check: the check ("reach", "joint limits", "collision", "straight move", ...).
        nearness: how near the candidate came (compared as a tuple: a later check, then a smaller
            shortfall, is nearer).
        what: the candidate and the check's numbers.
        fix: what the user can change.
    """

    check: str
    nearness: tuple[float, float]
    what: str
    fix: str


# How near a joint's limit (a fraction of its range) the closest configuration of a failed inverse
# kinematics must be for the limit to be named as in the way: the solver creeps up to a limit slowly.
AT_LIMIT = 0.02
# A failed pose whose hand is this near (m) but turned more than this (rad) is one the wrist cannot turn to.
NEAR, TURNED = 0.01, 0.05
FIT_MARGIN = 0.005  # m the tool frame should sit above the fingertips' depth that a fix suggests


def _xyz(position) -> str:
    return "(" + ", ".join(f"{v:.3f}" for v in position) + ")"


class Misses:
    """The checks failed while planning for ``arm``: each ``record`` adds one, :meth:`error` reports."""

    def __init__(self, arm) -> None:
        self.arm = arm
        self.file = arm.world.robot.description.file
        self.arm_field = f"{self.file}: arms.{arm.robot_arm.name}"
        self.found: list[Miss] = []

    def fits(self, width: float, needed: float) -> None:
        """No grasp yaw fits the object between the open fingers."""
        gripper, field = self.arm.gripper, f"{self.arm_field}.gripper"
        aperture = 2 * gripper.open
        if needed / 2 <= gripper.upper:
            fix = (
                f"open the fingers wider: {field}.open is {gripper.open:.4f} m per finger, the opening table "
                f"goes to {gripper.upper:.4f} (set open to at least {needed / 2:.4f})"
            )
        else:
            fix = "this gripper is too narrow for the object: a smaller object, or a gripper that opens wider"
        self.found.append(
            Miss(
                "gripper width",
                (-1.0, aperture - needed),
                f"the object is {width:.3f} m across its narrowest grasp and needs {needed:.3f} m between "
                f"the open fingers (clearance on both sides); they open {aperture:.3f} m",
                fix,
            )
        )

    def unreachable(self, pose: str, position, result, order: int) -> None:
        """Inverse kinematics found no configuration for a pose (the ``order``-th of its candidate)."""
        arm, where = self.arm, f"{pose} {_xyz(position)}"
        at_limit = [
            f"{name} at {value:+.3f} (range {low:+.3f} to {high:+.3f})"
            for name, value, low, high in zip(arm.joints, result.qpos, arm.lower, arm.upper, strict=True)
            if min(value - low, high - value) < AT_LIMIT * (high - low)
        ]
        turned = np.degrees(result.orientation_error)
        missed = f"the hand stays {result.position_error:.3f} m and {turned:.1f} deg from it"
        description = self.file
        if at_limit:
            check, what = "joint limits", f"{where}: {missed}, {'; '.join(at_limit)}"
            fix = (
                "the pose needs those joints beyond their ranges (the model's): an area nearer the arm "
                f"({description}: tabletop.reach, or the task's places) or a mount that faces it "
                f"({description}: mount)"
            )
        elif result.position_error < NEAR and result.orientation_error > TURNED:
            check, what = "hand orientation", f"{where}: the hand cannot point down there, {missed}"
            fix = (
                "the wrist cannot turn the hand down at this yaw here: check that "
                f"{self.arm_field}.tcp's z axis points out of the hand (down at the home keyframe) and its y "
                "axis along the fingers' closing"
            )
        else:
            check, what = "reach", f"{where}: out of reach, {missed}"
            fix = (
                f"bring the area nearer the arm ({description}: tabletop.reach) or the arm nearer "
                f"({description}: mount)"
            )
        self.found.append(Miss(check, (2.0 * order, -result.position_error), what, fix))

    def collision(self, pose: str, position, contact, order: int, lowest: bool) -> None:
        """The configuration found for a pose collides (``lowest``: the pose where the fingers are lowest,
        around the object or at the place)."""
        where = f"{pose} {_xyz(position)}"
        what = f"{where}: {contact.bodies} overlap {contact.depth * 1000:.1f} mm (geoms {contact.geoms})"
        if contact.hand and contact.furniture and lowest:
            fix = (
                "the fingertips reach lower than the tool frame allows for: the tool frame must sit between "
                f"the fingertips; move {self.arm_field}.tcp at least {contact.depth + FIT_MARGIN:.3f} m "
                "further along its z axis, toward the tips"
            )
        elif contact.furniture:
            fix = "a higher approach (the plan's approach_height, clearance), or an area off the furniture"
        elif not contact.hand:
            fix = (
                "the arm folds into the robot to reach this pose: an area farther from the robot's body "
                "(tabletop.reach); if the two parts touch in the model by design, exclude the pair there"
            )
        else:
            fix = "the hand meets something at this pose: another place, or the object farther from others"
        self.found.append(Miss("collision", (2.0 * order + 1, -contact.depth), what, fix))

    def crooked(self, move: str, deviation: float, allowed: float) -> None:
        """A vertical move strays from its straight line."""
        self.found.append(
            Miss(
                "straight move",
                (6.0, -deviation),
                f"{move} strays {deviation * 1000:.1f} mm from the straight "
                f"line ({allowed * 1000:.0f} mm allowed)",
                "the arm passes near a singularity or a joint limit on this move: an area nearer the middle "
                "of its workspace",
            )
        )

    def moving_collision(self, move: str, hit: str) -> None:
        """A planned move runs into something on its way."""
        self.found.append(
            Miss(
                "collision on the way",
                (7.0, 0.0),
                f"{move}: {hit} touch on the way",
                "the path passes through furniture or the robot: an area farther from them",
            )
        )

    def error(self, summary: str) -> PlanningError:
        """The error for a plan none of whose candidates passed: the nearest miss and a count per check."""
        if not self.found:
            return PlanningError(summary)
        nearest = max(self.found, key=lambda miss: miss.nearness)
        counts = Counter(miss.check for miss in self.found)
        tally = ", ".join(f"{check} {count}" for check, count in counts.most_common())
        return PlanningError(
            f"{summary}: {nearest.check} failed; nearest candidate: {nearest.what}. To change: {nearest.fix} "
            f"(checks failed over all candidates: {tally})"
        )
