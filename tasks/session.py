"""An interactive run in the browser: Run, Pause, Step, Reset and speed; a breakpoint; gizmos for the task.

A :class:`Session` holds a tree, the task it runs on (:mod:`besman.tasks`) and the task's values (pick and
place's ``object``: where the object stands and its yaw, ``place``: where it goes, ``shape`` and ``size``).
Its runs go in a background thread, driven by the viewer's controls:

- **Run** starts a run (a new one after the last has ended, or when a gizmo moved since this one was set up)
  or resumes a paused one; **Pause** stops after the current tick; **Step** runs one tick and pauses;
  **Reset** abandons the run and sets up a new one with the current task values; **speed** is the pace (x
  real time).
- **Breakpoint**: a node chosen in the list pauses the run at the first tick that visits it (once per run).
- A draggable gizmo marks each task value that begins with a point on a surface (:attr:`TaskValue.surface
  <besman.tasks.base.TaskValue.surface>`: pick and place's object and place target); it moves within the
  task's bounds, letting go of one sets that value's x and y (its other numbers, a yaw, stay), and the next
  run uses it (a tree that instantiates templates instantiates them for the new tau: it reads the task
  values when it runs). :meth:`Session.set_value` sets any task value; a run whose values change the world's
  objects (a shape, a size) shows them as they are: the viewer's scene is rebuilt with them.
- Overlays (:mod:`besman.sim.overlays`): the task's target (its value marked ``target``) as a ring, the
  motions' planned and executed hand paths, target frames, the objects' poses, a template's spread.

``besman run FILE --view`` and ``besman demo --view`` start the first run themselves (:meth:`Session.start`,
with the run's log if one is asked for) and keep serving the session after it.

The runner's observer (:class:`~besman.trees.watching.Watch`) does the waiting: between two ticks it blocks
while the session is paused, so the simulation stands exactly where the tree stopped.
"""

from __future__ import annotations

import copy
import os
import threading

import numpy as np
from py_trees.common import Status

from besman.core.errors import InputError
from besman.sim.viewer import Viewer, within
from besman.tasks import task as find_task
from besman.tasks.running import TaskRun, TreeSource, observers, prepare
from besman.trees.files import tree_task
from besman.trees.runner import Runner, RunResult
from besman.trees.watching import Watch

NO_BREAKPOINT = "(none)"
# s a closing session waits for the viewer's server to stop (its run it waits for: the run's log is closed
# as the run stops, at the end of its tick).
CLOSING_SECONDS = 5.0
# What the viewer draws of a model (meshes; inertia boxes): a run whose model differs in these (an object's
# shape or size) has the viewer's scene rebuilt.
GEOMETRY = (
    *("geom_type", "geom_size", "geom_pos", "geom_quat", "geom_rgba", "geom_rbound", "geom_aabb"),
    *("body_mass", "body_inertia", "body_ipos", "body_iquat"),
)


class _Abandoned(KeyboardInterrupt):
    """Raised inside a paused run's thread to end it (Reset); its log ends INTERRUPTED, as after Ctrl-C."""


class Session:
    """A tree on a task (default: the one its file names), run from the browser on ``robot`` (default: the
    task's); see the module documentation. ``pool`` and ``allow_modules`` as for
    :func:`~besman.tasks.running.prepare`, ``demo`` names the demo the session runs."""

    def __init__(
        self,
        tree: TreeSource,
        values: dict[str, tuple[float, ...]] | None = None,
        *,
        task: str | None = None,
        seed: int | None = None,
        speed: float = 1.0,
        viewer_options: dict | None = None,
        robot: str | None = None,
        pool=None,
        allow_modules=(),
        demo: str | None = None,
        perturb: str | None = None,
    ) -> None:
        from_file = isinstance(tree, str | os.PathLike)
        if task is None and not from_file:
            raise InputError("a tree built in code runs on a task: give task= (besman tasks lists them)")
        named = task or tree_task(tree)
        if named is None:
            raise InputError(f"{tree}: the tree names no task (a top-level 'task:' field): it is a subtree")
        self.task = find_task(named)
        self.tree, self.seed = tree, seed
        self.robot = self.task.check_robot(robot)
        self._options = {"pool": pool, "allow_modules": allow_modules, "demo": demo, "perturb": perturb}
        self.bounds = self.task.bounds(self.robot)
        self._lock = threading.Condition()
        self._running = False  # the run may tick
        self._steps = 0  # ticks left before pausing (-1: no limit)
        self._abandon = False
        self._closed = False  # close() was called: the page's buttons start nothing
        # Set when the run's thread has ended (None: no run started). Not Thread.join and is_alive: a Ctrl-C
        # that interrupts a join marks the thread as ended while it runs on (CPython gh-90882, Python 3.11),
        # and the session then closed the viewer under the running tree, or hung.
        self._ended: threading.Event | None = None
        self._watch: Watch | None = None  # made by the first tick of each run
        self._breakpoint_hit = False
        self._log = None  # the log of the next run (the first run's, from the command line)
        self.result: RunResult | None = None
        self.error: Exception | None = None  # what broke the last run, if anything did
        prepared = self._prepare(values or {})  # the task values not given: drawn, or the task's defaults
        self.values = {name: tuple(value) for name, value in prepared.runner.run_info["values"].items()}
        self.runner = self._new_runner(prepared)
        # a copy: the viewer's model takes the geometry of later runs' worlds (_show_objects)
        self.viewer = Viewer(copy.copy(self.runner.executor.world.model), **(viewer_options or {}))
        self.overlays = self.viewer.overlays_for(self.runner.executor.arm)
        gui = self.viewer.server.gui
        with gui.add_folder("Run"):
            self.run_button, self.pause_button = gui.add_button("Run"), gui.add_button("Pause")
            self.step_button, self.reset_button = gui.add_button("Step"), gui.add_button("Reset")
            self.speed = gui.add_slider(
                "speed (x real time)", min=0.1, max=max(10.0, speed), step=0.1, initial_value=speed
            )
            self.breakpoint = gui.add_dropdown(
                "break at", [NO_BREAKPOINT, *self.runner.paths.values()], initial_value=NO_BREAKPOINT
            )
            self.state = gui.add_markdown("ready")
        self.run_button.on_click(lambda _: self.run())
        self.pause_button.on_click(lambda _: self.pause())
        self.step_button.on_click(lambda _: self.step())
        self.reset_button.on_click(lambda _: self.reset())
        self.speed.on_update(lambda _: self._watch and setattr(self._watch, "speed", within(self.speed)))
        world = self.runner.executor.world
        self.surfaces = {  # the task values that are points on a surface: their gizmo's height
            value.name: world.surface(value.surface).height for value in self.task.values if value.surface
        }
        self.gizmos = {name: self._gizmo(name, height) for name, height in self.surfaces.items()}
        self._show_initial()

    # -- controls ------------------------------------------------------------------------------------------

    def run(self) -> None:
        """Starts a run (a new one after the last ended) or resumes the paused one."""
        self._go(-1)

    def start(self, log=None) -> RunResult:
        """Runs the set-up run to its end, writing ``log`` if given, and returns its result (the browser's
        controls work meanwhile: a pause holds this call; after the page's Reset, the run its Run starts
        next is the one waited for)."""
        self._log = log
        ended = self._go(-1)
        while True:
            ended.wait()
            with self._lock:
                if self.result is not None or self.error is not None:
                    break
                while self._ended in (None, ended):  # reset: until the page starts the next run
                    self._lock.wait()
                ended = self._ended
        if self.error is not None:
            raise self.error
        return self.result

    def step(self) -> None:
        """One tick, then pause."""
        self._go(1)

    def pause(self) -> None:
        with self._lock:
            self._running = False
            self._lock.notify_all()

    def reset(self) -> None:
        """Abandons the current run and sets up a new one with the current task values (nothing once the
        session is closed)."""
        with self._lock:
            if self._closed:
                return
        self._abandon_run()
        with self._lock:
            self._abandon, self._ended, self.result = False, None, None
        self.runner = self._new_runner(self._prepare(self.values))
        self._show_initial()

    @property
    def url(self) -> str:
        return self.viewer.url

    @property
    def paused(self) -> bool:
        with self._lock:
            return self._ended is not None and not self._ended.is_set() and not self._running

    def set_value(self, name: str, numbers) -> None:
        """Sets the task value ``name`` for the next run: its numbers, a choice's name (``"cylinder"``), or
        for a value on a surface (e.g. "object" or "place") x and y alone, which keep its other numbers (the
        yaw). Refused, by name, as the run would refuse it (outside the bounds, an object the gripper cannot
        hold)."""
        by_name = {value.name: value for value in self.task.values}
        if name not in by_name:
            raise InputError(
                f"{name!r} is not a value of task {self.task.name}; its values: {', '.join(by_name)}"
            )
        numbers = by_name[name].numbers(numbers)
        if name in self.surfaces and len(numbers) == 2:
            numbers = np.concatenate([numbers, self.values[name][2:]])
        given = {key: value for key, value in self.values.items() if key in by_name}
        resolved = self.task.resolve(self.robot, {**given, name: numbers}, self.seed)
        self.values.update({key: tuple(float(v) for v in value) for key, value in resolved.items()})
        if name in self.gizmos:
            self.gizmos[name].position = (*self.values[name][:2], self.gizmos[name].position[2])
        self._show_target()
        shown = ", ".join(f"{v:.3f}" for v in self.values[name])
        self.state.content = f"{name} set to ({shown}); Reset or Run uses it"

    def judge(self, result: RunResult):
        """The summary of the current run that ended with ``result`` (the task's judgement)."""
        return self.prepared.judge(result)

    def close(self) -> None:
        """Ends the session (Ctrl-C, the end of the command): the run stopped at its next tick (its log, if
        it writes one, closed), then the viewer, waited for at most :data:`CLOSING_SECONDS` - the command
        ends then, whatever the server's threads still do. The page's buttons start nothing after."""
        with self._lock:
            self._closed = True
        self._abandon_run()
        stopping = threading.Thread(target=self.viewer.close, daemon=True)
        stopping.start()
        stopping.join(CLOSING_SECONDS)

    # -- internals -----------------------------------------------------------------------------------------

    def _abandon_run(self) -> None:
        """Stops the run's thread at its next tick and waits for it."""
        with self._lock:
            self._abandon, self._running = True, False
            self._lock.notify_all()
            ended = self._ended
        if ended is not None:
            ended.wait()

    def _prepare(self, values: dict) -> TaskRun:
        return prepare(self.task, self.tree, robot=self.robot, seed=self.seed, values=values, **self._options)

    def _new_runner(self, prepared: TaskRun) -> Runner:
        self._watch, self._breakpoint_hit = None, False
        self._made_with = dict(self.values)
        self.prepared, runner = prepared, prepared.runner
        runner.observe = observers(runner.observe, self._observe)  # the task's own observer first
        return runner

    def _go(self, steps: int) -> threading.Event | None:
        """Runs ``steps`` ticks (-1: to the end), in a new run where the last has ended or the task values
        changed; the run's event, set when its thread ends (None once the session is closed)."""
        with self._lock:
            if self._closed:
                return None
            finished = self._ended is not None and self._ended.is_set()
        if finished or self._made_with != self.values:  # a new run after the last, or for moved task values
            self.reset()
        with self._lock:
            self._steps, self._running = steps, True
            if self._ended is None:
                self._ended = threading.Event()
                threading.Thread(target=self._run, args=(self._ended,), daemon=True).start()
            self._lock.notify_all()
            return self._ended

    def _run(self, ended: threading.Event) -> None:
        log, self._log, self.error = self._log, None, None
        try:
            self.result = self.runner.run(log=log)
            self.state.content = f"{self.result.status}: {self.result.message}"
        except _Abandoned:
            self.runner.root.stop(Status.INVALID)  # a tree given as an object runs again from its start
        except Exception as error:  # shown in the page, and raised again by start()
            self.error = error
            self.state.content = f"error: {error}"
        finally:
            ended.set()

    def _observe(self, runner: Runner, record: dict) -> None:
        if self._watch is None:
            self._watch = Watch(self.viewer, within(self.speed))
        self._watch(runner, record)
        with self._lock:
            if self._steps > 0:
                self._steps -= 1
                if self._steps == 0:
                    self._running = False
            target = self.breakpoint.value
            if not self._breakpoint_hit and target in record["statuses"]:
                self._running, self._breakpoint_hit = False, True
                self.state.content = f"paused at the breakpoint {target} (tick {record['tick']})"
            if not self._running and runner.root.status is Status.RUNNING:
                self.viewer.show(runner.executor.world.data, force=True)
                self.viewer.show_tree(record, list(runner.paths.values()))
                self._watch.restart_pacing()  # after the pause, real time counts from here
            while not self._running and not self._abandon and runner.root.status is Status.RUNNING:
                self._lock.wait()
            if self._abandon:
                raise _Abandoned

    def _show_initial(self) -> None:
        world = self.runner.executor.world
        self._show_objects(world.model)
        self.viewer.show(world.data, force=True)
        self.overlays.update(world.data)
        for name, handle in self.gizmos.items():
            handle.position = (*self.values[name][:2], handle.position[2])
        self._show_target()

    def _show_objects(self, model) -> None:
        """The viewer's scene rebuilt with ``model``'s geometry where the run's values changed it (the
        object's shape or size); every run of a task on a robot has the same bodies and geoms."""
        shown = self.viewer.scene.mj_model
        changed = [key for key in GEOMETRY if not np.array_equal(getattr(shown, key), getattr(model, key))]
        if not changed:
            return
        for key in changed:
            getattr(shown, key)[:] = getattr(model, key)
        self.viewer.scene.rebuild_visual_handles()

    def _show_target(self) -> None:
        """The task's target (its value marked ``target``) as a ring on its surface."""
        for value in self.task.values:
            if value.target and value.name in self.surfaces:
                self.overlays.show_place((*self.values[value.name][:2], self.surfaces[value.name]))

    def _gizmo(self, name: str, height: float):
        """A gizmo that moves in x and y within the task's bounds for ``name``; letting go sets x and y."""
        columns = self.bounds.columns(next(v.names[:2] for v in self.task.values if v.name == name))
        return self.viewer.planar_gizmo(
            f"/task/{name}",
            (*self.values[name][:2], height),
            columns.low,
            columns.high,
            scale=0.15,
            on_release=lambda xy: self.set_value(name, xy),
            status=self.state,
        )
