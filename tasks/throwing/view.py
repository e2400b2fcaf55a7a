"""A throwing skill template in the browser: where it aims, how sure it is, and where the ball lands.

:class:`ThrowingView` shows the PA-10 of the throwing task (:mod:`besman.tasks.throwing.rollouts`) with:

- the target tau on the floor (a green ring with a draggable gizmo, moving within the template's task box);
- the template's spread at tau: the hand paths of ``SPREAD_SAMPLES`` thetas drawn from N(Theta(tau),
  Sigma_tau) (grey: a wide fan where the template knows little) and the hand path of the mean (blue);
- the throw of the mean, simulated and played at real time: the arm, the ball's flight (orange) and its
  landing point (red) with the distance to the target in a label (or why the throw failed).

Letting go of the gizmo instantiates the template for the new target and throws again. The hand paths are
forward kinematics of the joint references the DMPs command (the same references the simulation tracks).
"""

from __future__ import annotations

import threading
import time

import mujoco
import numpy as np

from besman.core.errors import InputError
from besman.sim.arm import Arm
from besman.sim.overlays import EXECUTED, PLACE, PLANNED, SPREAD, SPREAD_SAMPLES, polyline
from besman.sim.viewer import MAX_FRAME_GAP, Viewer
from besman.skills.template import SkillTemplate
from besman.tasks.throwing.rollouts import ThrowingConfig, ThrowingRollouts

LANDING = (214, 39, 40)  # red
PATH_STRIDE = 10  # simulation steps between the drawn points of a hand path


def throwing_task_of(template: SkillTemplate) -> ThrowingRollouts:
    """The throwing task a template was learned on (its ``task``: "throwing/<variant>")."""
    kind, _, variant = template.task.partition("/")
    if kind != "throwing":
        raise InputError(f"template {template.name!r} is for {template.task or 'no task'!r}, not throwing")
    task = ThrowingRollouts(ThrowingConfig(variant=variant))
    if task.n_params != template.prototype.theta.size:
        raise InputError(
            f"template {template.name!r} has {template.prototype.theta.size} parameters, "
            f"the {variant} throwing task {task.n_params}"
        )
    return task


class ThrowingView:
    """A throwing template at a target, in a viewer (see the module documentation)."""

    def __init__(self, template: SkillTemplate, target=None, viewer_options: dict | None = None) -> None:
        self.template, self.task = template, throwing_task_of(template)
        box = template.box
        target = (np.asarray(box.low) + np.asarray(box.high)) / 2 if target is None else target
        self.target = tuple(box.check(target)[0])  # outside the box: named and refused
        self.arm = Arm(self.task.world)
        self.viewer = Viewer(self.task.model, **{"camera_distance": 10.0, **(viewer_options or {})})
        gui = self.viewer.server.gui
        with gui.add_folder("Throw"):
            self.status = gui.add_markdown("")
        self.gizmo = self.viewer.planar_gizmo(
            "/throw/target",
            (*self.target, 0.0),
            box.low,
            box.high,
            scale=0.6,
            on_release=self.throw,
            status=self.status,
        )
        self.landing: tuple[float, float] | None = None
        self._landing_marker = None
        self.failure: str | None = None
        self._busy = threading.Lock()

    @property
    def url(self) -> str:
        return self.viewer.url

    def throw(self, target=None, *, speed: float = 1.0) -> None:
        """Aims at ``target`` (default: the current one), draws the spread, and plays the mean's throw at
        ``speed`` x real time."""
        with self._busy:
            if target is not None:
                self.target = tuple(self.template.box.check(target)[0])
            self._aim()
            self._play(speed)

    def close(self) -> None:
        self.viewer.close()
        self.task.close()

    # -- internals -----------------------------------------------------------------------------------------

    def _hand_paths(self, thetas: np.ndarray) -> list[np.ndarray]:
        references = self.task.dmp.trajectories(thetas, run_time=self.task.execution_time, derivatives=0)
        joints = references.positions[:, ::PATH_STRIDE, : self.arm.dofs]
        return [self.arm.site_path(path) for path in joints]

    def _aim(self) -> None:
        scene, tau = self.viewer.server.scene, np.asarray(self.target)
        mean = self.template.predict(tau)[0]
        samples = self.template.sample(tau, SPREAD_SAMPLES, seed=0)
        *spread, planned = self._hand_paths(np.vstack([samples, mean]))
        scene.add_line_segments(
            "/throw/spread", np.concatenate([polyline(p) for p in spread]), SPREAD, thickness=0.006
        )
        scene.add_line_segments("/throw/planned", polyline(planned), PLANNED, thickness=0.012)
        ring = np.linspace(0.0, 2.0 * np.pi, 49)
        circle = np.column_stack([0.25 * np.cos(ring), 0.25 * np.sin(ring), np.full(49, 0.01)])
        scene.add_line_segments("/throw/ring", polyline(circle + [*tau, 0.0]), PLACE, thickness=0.03)
        self.gizmo.position = (*tau, 0.0)
        if self._landing_marker is not None:  # the last throw's
            self._landing_marker.remove()
            self._landing_marker = None
        self._qpos, detail = self.task.simulate(mean)
        self.landing, self.failure, self.release = detail.landing, detail.failure, detail.release_time

    def _play(self, speed: float) -> None:
        """The throw, frame by frame at ``speed`` x real time; the ball's flight drawn as it goes."""
        scene, task, data = self.viewer.server.scene, self.task, self.task.world.data
        if self._qpos is None:
            self.status.content = f"the throw fails before it starts: {self.failure}"
            return
        ball = task.model.jnt_qposadr[task.model.body_jntadr[task.ball]]
        heights = self._qpos[:, ball + 2]
        release = np.inf if self.release is None else self.release  # never released: no flight
        after_release = np.arange(len(heights)) * task.timestep >= release
        on_floor = np.flatnonzero(after_release & (heights <= task.ball_radius))
        # The flight ends at the landing (the ball's first floor contact); the play half a second later.
        landed = on_floor[0] if on_floor.size else len(heights) - 1
        end = min(len(heights) - 1, landed + round(0.5 / task.timestep))
        released = int(np.argmax(after_release)) if after_release.any() else len(heights)
        start, step = time.perf_counter(), 0
        while True:
            data.qpos[:] = self._qpos[step]
            mujoco.mj_kinematics(task.model, data)
            self.viewer.show(data, force=True)
            # The ball's path so far (whatever frames the pace skipped), up to its landing.
            if step > released:
                last = min(step, landed)
                flight = self._qpos[np.r_[released:last:PATH_STRIDE, last], ball : ball + 3]
                scene.add_line_segments("/throw/flight", polyline(flight), EXECUTED, thickness=0.01)
            if step == end:
                break
            time.sleep(MAX_FRAME_GAP / 2)  # frames well within the gap, whatever the flight's drawing costs
            step = min(end, int((time.perf_counter() - start) * speed / task.timestep))
        tau = np.asarray(self.target)
        if self.landing is None:
            self.status.content = f"target ({tau[0]:.2f}, {tau[1]:.2f}) m: the throw fails: {self.failure}"
            return
        distance = float(np.linalg.norm(np.asarray(self.landing) - tau))
        self._landing_marker = scene.add_icosphere(
            "/throw/landing", radius=0.08, color=LANDING, position=(*self.landing, 0.0)
        )
        scene.add_label("/throw/landing/label", f"{distance:.2f} m from the target", anchor="bottom-left")
        self.status.content = (
            f"target ({tau[0]:.2f}, {tau[1]:.2f}) m: landed at "
            f"({self.landing[0]:.2f}, {self.landing[1]:.2f}), {distance:.2f} m away"
        )
