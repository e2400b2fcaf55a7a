"""What the viewer draws over the world: where the hand is meant to go and where it went.

- **planned path**: the hand's path along the current motion's joint reference (the Ruckig executor tracks
  that reference; forward kinematics of its samples), drawn when the motion starts;
- **executed path**: the hand's measured positions since that motion started, growing with every frame;
- **target frames**: the hand's pose at the end of the reference (where the motion will leave it);
- **objects and place**: every object's pose (a frame that moves with it) and the place target, a ring on
  its surface;
- **template spread**: for a skill template instantiated at tau, the hand paths of primitives whose theta
  is drawn from the template's Gaussian N(Theta(tau), Sigma_tau): their spread is the template's uncertainty
  made visible (a wide fan where the template knows little).

Each kind has a toggle in the viewer's "Overlays" folder. Positions are in the world frame (viser's scene
frame is MuJoCo's world frame: z up).
"""

from __future__ import annotations

import time

import numpy as np
import viser

from besman.sim.arm import Arm
from besman.sim.motions import FollowReference, Motion
from besman.sim.references import hand_path
from besman.skills.template import SkillTemplate

PLANNED = (31, 119, 180)  # blue
EXECUTED = (255, 127, 14)  # orange
SPREAD = (120, 120, 120)  # grey
PLACE = (44, 160, 44)  # green
EXECUTED_STEP = 0.01  # m the hand moves before the executed path grows by a point
EXECUTED_PERIOD = 0.2  # s of wall time between two drawings of the executed path
PATH_SAMPLE_PERIOD = 0.02  # s between the drawn points of a planned path
SPREAD_SAMPLES = 16
LINE_WIDTH = 3.0  # pixels: the same on screen however far the camera is
KINDS = {  # each kind of overlay and its toggle's label
    "planned": "planned hand path",
    "executed": "executed hand path",
    "targets": "target frames",
    "objects": "objects and place",
    "spread": "template spread",
}


def polyline(points: np.ndarray) -> np.ndarray:
    """Line segments (N - 1, 2, 3) joining consecutive points (N, 3)."""
    points = np.asarray(points, dtype=np.float32)
    return np.stack([points[:-1], points[1:]], axis=1)


def template_spread(
    arm: Arm,
    template: SkillTemplate,
    tau,
    state: tuple[np.ndarray, np.ndarray, np.ndarray],
    count: int = SPREAD_SAMPLES,
    seed: int = 0,
) -> list[np.ndarray]:
    """Hand paths (each (K, 3)) of ``count`` primitives with theta ~ N(Theta(tau), Sigma_tau), started in the
    joint ``state`` (seeded: the same fan for the same template, tau and seed)."""
    thetas = template.sample(tau, count, seed)
    return [hand_path(arm, template.primitive(theta, tau), state, PATH_SAMPLE_PERIOD) for theta in thetas]


class Overlays:
    """The overlays of one arm's motions in a viewer's scene (see the module documentation)."""

    def __init__(self, server: viser.ViserServer, arm: Arm) -> None:
        self.server, self.arm = server, arm
        self._motion: Motion | None = None
        self._executed: list[np.ndarray] = []
        self._drawn = -np.inf  # wall time the executed path was last drawn
        self._objects: dict = {}  # per object, its frame
        self._handles: dict[str, list] = {kind: [] for kind in KINDS}
        with server.gui.add_folder("Overlays"):
            self.toggles = {
                kind: server.gui.add_checkbox(label, initial_value=True) for kind, label in KINDS.items()
            }
        for kind, toggle in self.toggles.items():
            toggle.on_update(lambda _, kind=kind: self._set_visible(kind))

    def update(self, data, *, final: bool = False) -> None:
        """Follows the objects and the hand (called with every frame of the scene; ``final`` for the run's
        last, which draws the executed path whole)."""
        world = self.arm.world
        for name in world.objects:
            pose = world.object_pose(name)
            frame = self._objects.get(name)
            if frame is None:
                self._objects[name] = self._put(
                    "objects",
                    f"/overlays/objects/{name}",
                    self.server.scene.add_frame,
                    axes_length=0.08,
                    axes_radius=0.004,
                    position=pose.position,
                    wxyz=pose.quaternion,
                )
            else:  # moved, not made again: a new scene node costs every browser far more than a pose
                frame.position, frame.wxyz = pose.position, pose.quaternion
        hand = data.site(self.arm.site).xpos.copy()
        if len(self._executed) == 0 or final or np.linalg.norm(hand - self._executed[-1]) > EXECUTED_STEP:
            self._executed.append(hand)
            now = time.perf_counter()
            # A new line with every frame would make every browser rebuild it some 30 times a second.
            if len(self._executed) > 1 and (final or now - self._drawn >= EXECUTED_PERIOD):
                self._drawn = now
                self._line("executed", "/overlays/executed", polyline(self._executed), EXECUTED)

    def follow(self, motion: Motion | None) -> None:
        """Draws a newly started motion's planned path and target frame; the executed path starts again."""
        if motion is self._motion:
            return
        self._motion = motion
        if not isinstance(motion, FollowReference) or motion.reference is None:
            return
        reference = motion.reference
        stride = max(1, round(PATH_SAMPLE_PERIOD / (reference.times[1] - reference.times[0])))
        planned = self.arm.site_path(np.r_[reference.positions[::stride], reference.positions[-1:]])
        goal = self.arm.site_pose(reference.positions[-1])
        self._executed = []
        self._line("planned", "/overlays/planned", polyline(planned), PLANNED)
        self._put(
            "targets",
            "/overlays/target",
            self.server.scene.add_frame,
            axes_length=0.1,
            axes_radius=0.005,
            position=goal.position,
            wxyz=goal.quaternion,
        )
        self._put(
            "targets",
            "/overlays/target/label",
            self.server.scene.add_label,
            text=motion.name,
            anchor="bottom-left",
        )

    def show_place(self, position) -> None:
        """The place target: a green ring of 5 cm radius at ``position`` (x, y, z of the surface)."""
        angles = np.linspace(0.0, 2.0 * np.pi, 33)
        ring = np.column_stack([0.05 * np.cos(angles), 0.05 * np.sin(angles), np.full(33, 0.002)])
        self._line("objects", "/overlays/place", polyline(ring + np.asarray(position, dtype=float)), PLACE)

    def show_spread(self, paths: list[np.ndarray]) -> None:
        """A template's fan of hand paths (:func:`template_spread`)."""
        segments = np.concatenate([polyline(path) for path in paths])
        self._line("spread", "/overlays/spread", segments, SPREAD, width=LINE_WIDTH / 2)

    def _line(self, kind: str, name: str, segments: np.ndarray, colour, width: float = LINE_WIDTH):
        """Adds (or replaces) an overlay of ``kind``: line ``segments`` (N, 2, 3), ``width`` pixels wide."""
        self._put(
            kind,
            name,
            self.server.scene.add_line_segments,
            points=segments,
            colors=colour,
            thickness=width,
            thickness_units="screen",
        )

    def _put(self, kind: str, name: str, add, **arguments):
        """Adds (or replaces: viser replaces a scene node of the same name) one overlay node of ``kind``."""
        handle = add(name, visible=self.toggles[kind].value, **arguments)
        self._handles[kind] = [h for h in self._handles[kind] if h.name != name] + [handle]
        return handle

    def _set_visible(self, kind: str) -> None:
        for handle in self._handles[kind]:
            handle.visible = self.toggles[kind].value
