"""A run's summary: one type for every demo and every ``besman run``, and the one shape of their ``--json``.

A tree's status says whether its root succeeded; whether the task was done is measured in the simulation
afterwards (the box within 2 cm of its place, the ball within 0.5 m of its target, the arms never touching).
A summary holds both - ``status`` from the tree, ``success`` from the measurements - beside the run's
configuration and its cost, and it says in one line what it measured (``outcome``), so that nothing that
prints a summary needs to know which task it came from.

The JSON document (:meth:`RunSummary.to_json`, printed by ``--json``) has ``schema_version`` 2 and
``kind`` ``"besman-run-summary"``, then every field below in this order; ``measurements`` is the only
object whose keys depend on the task (each demo's are listed with the command line's pages).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

from besman.trees.runner import Runner, RunResult

SCHEMA_VERSION = 3  # 2: the task; 3: the first failure a retry absorbed
KIND = "besman-run-summary"


@dataclass(frozen=True)
class Measured:
    """What a task measured of a run: whether the task was done, one line saying what was measured, and
    the measured values by name (metres, seconds, counts; JSON values)."""

    done: bool
    outcome: str
    measurements: dict = field(default_factory=dict)


@dataclass(frozen=True)
class RunSummary:
    """How a run went.

    Attributes:
        success: the tree succeeded and the task's measurements say it was done.
        status: the tree's final status: ``SUCCESS`` or ``FAILURE``.
        outcome: one line on what was measured, e.g. ``placement error 0.0 cm``.
        measurements: the measured values by name (``placement_error_m``, ``miss_m``...; per task).
        task: the task the tree ran on.
        demo: the demo's name (its task's), or None for a tree run with ``besman run``.
        tree: the tree file that ran (or the tree itself, described, when it was built in code), with the
            pool that replaced the pools it names (``--pool``).
        robot: the robot's name.
        seed: the seed that drew the configuration, or None.
        settings: the run's configuration: the values on the blackboard's ``/task/`` and where objects stood.
        sim_time_s: simulated seconds.
        wall_time_s: wall-clock seconds.
        ticks: ticks of the tree.
        failed_node: the path of the node whose failure ended the run, or None.
        message: that node's feedback message, or the runner's reason (e.g. the simulated-time limit).
    """

    success: bool
    status: str
    outcome: str
    measurements: dict
    task: str
    demo: str | None
    tree: str
    robot: str
    seed: int | None
    settings: dict
    sim_time_s: float
    wall_time_s: float
    ticks: int
    failed_node: str | None
    message: str
    first_failure: str | None

    @classmethod
    def of(cls, runner: Runner, result: RunResult, measured: Measured) -> RunSummary:
        """The summary of ``runner``'s run that ended with ``result``, the task having measured
        ``measured``; what was run (task, demo, tree, robot, seed, settings) comes from the runner's log
        header."""
        info = runner.run_info
        tree = info["tree"]
        if isinstance(tree, str) and info.get("pool"):
            tree += f" (--pool {info['pool']})"
        return cls(
            success=result.status == "SUCCESS" and measured.done,
            status=result.status,
            outcome=measured.outcome,
            measurements=measured.measurements,
            task=info["task"],
            demo=info.get("demo"),
            tree=tree if isinstance(tree, str) else f"{runner.root.name} (built in code)",
            robot=info["robot"],
            seed=info.get("seed"),
            settings=info.get("settings", {}),
            sim_time_s=result.sim_time_s,
            wall_time_s=result.wall_time_s,
            ticks=result.ticks,
            failed_node=result.failed_node,
            message=result.message,
            first_failure=result.first_failure,
        )

    def to_json(self) -> dict:
        """The summary as the ``--json`` document: ``schema_version``, ``kind``, then the fields in order."""
        return {"schema_version": SCHEMA_VERSION, "kind": KIND, **asdict(self)}

    def text(self) -> str:
        """The summary for people: its outcome and cost on one line, then the failed node if there is one."""
        head = "SUCCESS" if self.success else "FAILURE"
        if not self.success and self.status == "SUCCESS":
            head += " (the tree succeeded, the task was not done)"
        line = (
            f"{head}: {self.outcome}; {self.sim_time_s:.1f} s simulated in {self.wall_time_s:.1f} s, "
            f"{self.ticks} ticks"
        )
        failed = f"\nfailed at {self.failed_node}: {self.message}" if self.failed_node else ""
        first = f"\nfirst failed at {self.first_failure} (then retried)" if self.first_failure else ""
        return line + failed + first
