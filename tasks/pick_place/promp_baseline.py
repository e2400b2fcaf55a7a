"""ProMP conditioning as a baseline beside the skill templates: the same blocks, the same training tasks.

A skill template predicts a block's DMP parameters from the hand's move (:mod:`besman.skills.template`).
The baseline instead learns the distribution of the block's joint trajectories in its K training tasks as a
Probabilistic Movement Primitive (Paraschos et al., NIPS 2013; :class:`movement_primitives.promp.ProMP`)
and, for a new move, conditions it on the move's start and end configurations (via-points at normalised
times 0 and 1). Its mean trajectory is imitated by the project's joint-space DMP (the prototype's basis
and duration, at rest at both ends, as :func:`besman.learning.pipeline.retargeting.retarget` imitates a
shape), which the planners then move exactly to the end points (:func:`besman.sim.primitives.shaped`).

The training trajectories are what the learned thetas execute in the training tasks: each task's theta in
the template's prototype, moved to the block's planned start and end configurations for that task
(:func:`besman.tasks.pick_place.blocks.start`, the same preparation the refinement rolled out from),
sampled at the prototype's steps and time-normalised to :data:`STEPS` samples. The moves are planned again
by today's planner: where it plans a training task's move otherwise than when the pool was learned, the
learned theta is shaped to the new move, as the template's instances are (:func:`changed_moves` lists
those tasks).

The baseline's one setting, the ProMP's weights per joint, is chosen from :data:`WEIGHT_CHOICES` by a
declared procedure on the training trajectories only (:func:`select_weights`): leave-one-out over the K
tasks - fit on K - 1, condition on the held-out task's start and end configurations, and measure the RMSE
(rad, over joints and time) of the primitive's joint trajectory against the held-out one; among the
settings whose held-out primitives the arm can follow (every joint within its acceleration limit, as the
templates' own primitives must be: the executor cannot run one that is not), the smallest mean RMSE wins,
ties to fewer weights; where none is, the setting that passes the limits least. The selection is recorded
in the baseline's provenance, with each candidate's largest joint acceleration over the held-out primitives
as a share of its limit.

Nothing is stored: a baseline is rebuilt from the pool's files (:func:`baseline_pool`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from movement_primitives.promp import ProMP

from besman.core.errors import InputError
from besman.skills import DMP, MovementPrimitive, SkillTemplate, SkillTemplatePool

WEIGHT_CHOICES = (4, 6, 8, 10, 15)  # the ProMP's weights per joint that leave-one-out chooses from
STEPS = 101  # samples of a time-normalised trajectory: the EM's matrices grow with (steps * joints)^2
INPUT_TOLERANCE = 1e-3  # m and deg: a training move prepared again that differs more has changed


@dataclass(frozen=True)
class TrainingMoves:
    """A block's training moves: the planned start and end configurations (K, D), the joint trajectories
    (K, T, D) the learned thetas execute between them, sampled at the prototype's steps, and the moves'
    template inputs (K, m) as planned now (:func:`changed_moves` compares them with those learned)."""

    starts: np.ndarray
    ends: np.ndarray
    trajectories: np.ndarray
    inputs: np.ndarray
    max_acceleration: np.ndarray | None = None  # (D,) the arm's limits (rad/s^2); None: no limit

    def __post_init__(self) -> None:
        if np.ndim(self.trajectories) != 3:
            raise InputError(f"trajectories must be (K, T, D), got shape {np.shape(self.trajectories)}")
        count, steps, dofs = np.shape(self.trajectories)
        if np.shape(self.starts) != (count, dofs) or np.shape(self.ends) != (count, dofs):
            raise InputError(
                f"starts and ends must be ({count}, {dofs}) as the trajectories, got "
                f"{np.shape(self.starts)} and {np.shape(self.ends)}"
            )
        if len(self.inputs) != count:
            raise InputError(f"need an input per trajectory, got {len(self.inputs)} for {count}")
        if count < 2 or steps < 3:
            raise InputError(f"need at least 2 trajectories of 3 samples, got {count} of {steps}")


def training_moves(template: SkillTemplate, robot: str | None = None) -> TrainingMoves:
    """The moves of ``template``'s block (its name: reach, carry or return) in its pick-and-place training
    tasks (its provenance's ``training`` entries and thetas), prepared again in MuJoCo on ``robot`` (default:
    the robot the template was learned on), with the planner as it is now: a task whose move the planner
    has changed since (another grasp, say) gives the learned theta shaped to the new move, as the template
    itself is used (:func:`changed_moves` counts them)."""
    from besman.sim.block_simulation import block_input
    from besman.sim.executor import Executor
    from besman.sim.primitives import shaped
    from besman.tasks.pick_place.blocks import start, world

    robot = robot or template.provenance.get("robot")
    training = template.provenance.get("training") or []
    if robot is None or len(training) != len(template.thetas) or any("task_tau" not in t for t in training):
        raise InputError(
            f"template {template.name!r}: its provenance must name the robot and give each training task's "
            "task_tau (a pool learned by besman learn on the task's whole tau)"
        )
    starts, ends, trajectories, inputs, limits = [], [], [], [], None
    for record, theta in zip(training, template.thetas, strict=True):
        built = world(robot, record["task_tau"])
        begins = start(built, template.name, record["task_tau"])
        arm = Executor(built).arm
        executed = shaped(
            template.primitive(theta, record["tau"]), template.name, begins.start, begins.goal, arm
        )
        starts.append(begins.start)
        ends.append(begins.goal)
        trajectories.append(executed.dmp.trajectory().positions)
        inputs.append(block_input(arm, begins.start, begins.goal))
        limits = arm.max_acceleration
    return TrainingMoves(*(np.array(v) for v in (starts, ends, trajectories, inputs)), limits)


def changed_moves(template: SkillTemplate, moves: TrainingMoves) -> list[int]:
    """The training tasks whose move (template input) differs from the one the template learned, beyond
    :data:`INPUT_TOLERANCE` (the hand's turn modulo 360 deg; the wrap leaves differences in metres alone)."""
    difference = (moves.inputs - template.taus + 180.0) % 360.0 - 180.0
    return np.flatnonzero(np.abs(difference).max(axis=1) > INPUT_TOLERANCE).tolist()


def normalised(trajectories: np.ndarray, steps: int = STEPS) -> np.ndarray:
    """(K, T, D) trajectories resampled at ``steps`` evenly spaced normalised times in [0, 1]."""
    samples = np.linspace(0.0, 1.0, trajectories.shape[1])
    times = np.linspace(0.0, 1.0, steps)
    return np.stack([np.column_stack([np.interp(times, samples, y) for y in t.T]) for t in trajectories])


def fit(trajectories: np.ndarray, weights: int) -> ProMP:
    """A ProMP with ``weights`` per dimension imitating time-normalised (K, STEPS, D) trajectories (the
    library's EM with its defaults)."""
    count, steps, dofs = trajectories.shape
    promp = ProMP(dofs, n_weights_per_dim=weights)
    # The library divides the time arrays it is given by their last time in place: it gets its own.
    promp.imitate(np.tile(np.linspace(0.0, 1.0, steps), (count, 1)), trajectories)
    return promp


def conditioned_mean(promp: ProMP, start: np.ndarray, end: np.ndarray, steps: int = STEPS) -> np.ndarray:
    """The mean (steps, D) of ``promp`` conditioned to be at ``start`` at time 0 and at ``end`` at time 1."""
    conditioned = promp.condition_position(np.asarray(start, float), t=0.0)
    conditioned = conditioned.condition_position(np.asarray(end, float), t=1.0)
    return conditioned.mean_trajectory(np.linspace(0.0, 1.0, steps))


def joint_primitive(
    mean: np.ndarray, start: np.ndarray, end: np.ndarray, prototype: MovementPrimitive, name: str
) -> MovementPrimitive:
    """A joint-space primitive from ``start`` to ``end`` imitating the time-normalised path ``mean`` with
    ``prototype``'s DMP basis, duration and step, starting and ending at rest."""
    shape = prototype.dmp
    times = np.linspace(0.0, shape.execution_time, len(mean))
    # At rest at both ends (as shaped moves it), so that the forcing term, not boundary velocities estimated
    # from the path, carries the shape.
    velocities = np.gradient(mean, times, axis=0, edge_order=2)
    velocities[[0, -1]] = 0.0
    accelerations = np.gradient(velocities, times, axis=0, edge_order=2)
    accelerations[[0, -1]] = 0.0
    dmp = DMP(shape.n_dims, settings=shape.settings, dt=shape.dt, scale=shape.scale)
    dmp.imitate(times, mean, velocities=velocities, accelerations=accelerations)
    dmp.configure(start=start, goal=end, start_velocity=0.0, start_acceleration=0.0, goal_velocity=0.0)
    return MovementPrimitive(dmp, name, robot=prototype.robot, group=prototype.group)


def select_weights(
    moves: TrainingMoves, prototype: MovementPrimitive, candidates: Sequence[int] = WEIGHT_CHOICES
) -> dict:
    """The weights per joint chosen by leave-one-out on the training moves (see the module documentation):
    the candidates' mean RMSE (rad), their largest joint acceleration over the held-out primitives as a
    share of the joint's limit (a conditioned mean can swerve sharply to a via-point off the training
    moves' course), and the chosen one: the smallest RMSE of those within the limits, or if none is, the
    one that passes them least."""
    paths = normalised(moves.trajectories)
    limits = np.inf if moves.max_acceleration is None else np.asarray(moves.max_acceleration)
    rmse, peaks = {}, {}
    for weights in candidates:
        errors, peak = [], 0.0
        for held in range(len(paths)):
            promp = fit(np.delete(paths, held, axis=0), weights)
            mean = conditioned_mean(promp, moves.starts[held], moves.ends[held])
            primitive = joint_primitive(mean, moves.starts[held], moves.ends[held], prototype, "held out")
            executed = primitive.dmp.trajectory()
            errors.append(float(np.sqrt(np.mean((executed.positions - moves.trajectories[held]) ** 2))))
            peak = max(peak, float((np.abs(executed.accelerations) / limits).max()))
        rmse[int(weights)], peaks[int(weights)] = float(np.mean(errors)), peak
    followable = [weights for weights in rmse if peaks[weights] <= 1.0]
    if followable:
        chosen = min(followable, key=lambda weights: (rmse[weights], weights))
    else:  # the one the arm comes nearest to following
        chosen = min(rmse, key=lambda weights: (peaks[weights], weights))
    return {
        "procedure": "leave-one-out over the training moves: fit on K - 1, condition on the held-out move's "
        "start and end, RMSE (rad) of the primitive's joint trajectory; of the settings whose held-out "
        "primitives keep every joint within its acceleration limit, the smallest mean, ties to fewer weights "
        "(none within them: the smallest peak acceleration)",
        "candidates": [int(w) for w in candidates],
        "rmse_rad": rmse,
        "peak_acceleration_share_of_limit": peaks,
        "weights_per_joint": chosen,
    }


class ProMPBaseline:
    """A block's ProMP baseline, in a pool beside (or instead of) its skill template: ``name``, ``box`` (the
    template's input box, which the tree leaves check) and ``provenance`` (the robot, the setting and how it
    was chosen); :meth:`primitive_for_move` gives the primitive for a move.

    Args:
        template: the block's skill template (its prototype, box, robot and training tasks).
        moves: its training moves (:func:`training_moves`).
        weights: the ProMP's weights per joint; None chooses them from ``candidates`` by
            :func:`select_weights`.
    """

    def __init__(
        self,
        template: SkillTemplate,
        moves: TrainingMoves,
        weights: int | None = None,
        candidates: Sequence[int] = WEIGHT_CHOICES,
    ) -> None:
        if moves.trajectories.shape[0] != len(template.thetas):
            raise InputError(
                f"template {template.name!r} has {len(template.thetas)} training tasks, the moves "
                f"{moves.trajectories.shape[0]}"
            )
        self.name, self.box, self.prototype = template.name, template.box, template.prototype
        selection = (
            select_weights(moves, self.prototype, candidates)
            if weights is None
            else {"procedure": "given", "weights_per_joint": weights}
        )
        self.weights = int(selection["weights_per_joint"])
        self.promp = fit(normalised(moves.trajectories), self.weights)
        self.provenance = {
            "robot": template.provenance.get("robot"),
            "baseline": "ProMP conditioned on the move's start and end configurations",
            "template": template.name,
            "training_tasks": len(template.thetas),
            "changed_training_moves": changed_moves(template, moves),
            "selection": selection,
        }

    def primitive_for_move(self, start: np.ndarray, end: np.ndarray) -> MovementPrimitive:
        """The joint-space primitive from configuration ``start`` to ``end``: the ProMP's mean conditioned
        on them, imitated by the prototype's DMP."""
        mean = conditioned_mean(self.promp, start, end)
        return joint_primitive(mean, start, end, self.prototype, self.name)

    def __repr__(self) -> str:
        return f"ProMPBaseline({self.name!r}, weights={self.weights})"


def baseline_pool(
    pool: str | Path | SkillTemplatePool,
    moves: dict[str, TrainingMoves] | None = None,
    weights: dict[str, int] | None = None,
) -> dict[str, ProMPBaseline]:
    """A :class:`ProMPBaseline` per template of ``pool``, from its training moves (prepared again unless
    given) and with its weights (chosen by leave-one-out unless given): a mapping that tree files can name
    once registered (:func:`besman.trees.registry.register_pool`)."""
    templates = pool if isinstance(pool, SkillTemplatePool) else SkillTemplatePool(pool)
    moves, weights = moves or {}, weights or {}
    baselines = {}
    for name in templates:
        template = templates[name]
        found = moves[name] if name in moves else training_moves(template)
        baselines[name] = ProMPBaseline(template, found, weights.get(name))
    return baselines
