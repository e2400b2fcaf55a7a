"""One Ruckig stream: a commanded joint state moved one control cycle at a time within jerk limits.

Ruckig (community edition) is used for one state-to-state update per cycle, never for intermediate
waypoints. Because every update starts from the last commanded position, velocity and acceleration, motions
chain with continuous position, velocity and acceleration and can be pre-empted at any cycle. The same
stream drives an arm (n joints) and a gripper (one).

Targets are made acceptable to Ruckig before they are given (:meth:`JerkLimitedStream.feasible`): within
the range and the limits, and with an acceleration that can be brought to zero before the velocity passes
its limit. A target on a joint's range limit is a target at rest there.
"""

from __future__ import annotations

import numpy as np
import ruckig

WORKING = (ruckig.Result.Working, ruckig.Result.Finished)
# s: the longest trajectory Ruckig computes; longer, it returns a result (-101) its Python binding cannot
# name (a ValueError).
LONGEST = 7.6e3
# The shares of the velocity and acceleration limits a target may have (room to stop accelerating before the
# velocity limit); a reference meant to be tracked keeps within them (Arm.slowdown).
VELOCITY_SHARE, ACCELERATION_SHARE = 0.99, 0.999
ARRIVED = 1e-9  # rad (m), per s, per s^2: a commanded state this close to its target has reached it


class JerkLimitedStream:
    """The commanded state of ``len(lower)`` joints, advanced every ``period`` seconds by Ruckig."""

    def __init__(self, lower, upper, max_velocity, max_acceleration, max_jerk, period: float) -> None:
        self.lower, self.upper = np.asarray(lower, float), np.asarray(upper, float)
        self.max_velocity = np.asarray(max_velocity, float)
        self.max_acceleration = np.asarray(max_acceleration, float)
        self.max_jerk = np.asarray(max_jerk, float)
        self.dofs = len(self.lower)
        self._otg = ruckig.Ruckig(self.dofs, period)
        self._input = ruckig.InputParameter(self.dofs)
        self._output = ruckig.OutputParameter(self.dofs)
        self._input.max_velocity = self.max_velocity.tolist()
        self._input.max_acceleration = self.max_acceleration.tolist()
        self._input.max_jerk = self.max_jerk.tolist()
        # Ruckig accepts a target velocity v only with room to stop accelerating after it, or to have
        # been slowing down to it: |a| <= sqrt(2 j (v_max - |v|)) whichever way a points.
        self._velocity_bound = VELOCITY_SHARE * self.max_velocity
        self._acceleration_bound = ACCELERATION_SHARE * self.max_acceleration
        self.reset(np.clip(np.zeros(self.dofs), self.lower, self.upper))

    def reset(self, position) -> None:
        """Takes ``position`` as the commanded state, at rest."""
        inputs = self._input
        inputs.current_position = [float(value) for value in position]
        inputs.current_velocity = [0.0] * self.dofs
        inputs.current_acceleration = [0.0] * self.dofs

    # The commanded state lives in Ruckig's input: each output is passed on to the next input, never back
    # through Python, and arrays are made only when asked for.

    @property
    def position(self) -> np.ndarray:
        return np.array(self._input.current_position)

    @property
    def velocity(self) -> np.ndarray:
        return np.array(self._input.current_velocity)

    @property
    def acceleration(self) -> np.ndarray:
        return np.array(self._input.current_acceleration)

    def state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The commanded (position, velocity, acceleration)."""
        return self.position, self.velocity, self.acceleration

    def state_lists(self) -> tuple[list[float], list[float], list[float]]:
        """The commanded state as lists of floats (cheapest to log and compare)."""
        inputs = self._input
        return inputs.current_position, inputs.current_velocity, inputs.current_acceleration

    @property
    def at_rest_exactly(self) -> bool:
        inputs = self._input
        return not any(inputs.current_velocity) and not any(inputs.current_acceleration)

    @property
    def at_rest(self) -> bool:
        inputs = self._input
        return (
            max(map(abs, inputs.current_velocity)) < 1e-6
            and max(map(abs, inputs.current_acceleration)) < 1e-6
        )

    def feasible(self, position, velocity, acceleration) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Target states (..., dofs) Ruckig accepts: positions in the range, velocities and accelerations
        clipped to the limits and the stopping headroom, and at rest wherever a position was clipped."""
        clipped = np.clip(position, self.lower, self.upper)
        velocity = np.clip(velocity, -self._velocity_bound, self._velocity_bound)
        acceleration = np.clip(acceleration, -self._acceleration_bound, self._acceleration_bound)
        headroom = np.sqrt(2.0 * self.max_jerk * np.maximum(self._velocity_bound - np.abs(velocity), 0.0))
        acceleration = np.clip(acceleration, -headroom, headroom)
        at_limit = clipped != position  # a joint held at its limit stops there
        return clipped, np.where(at_limit, 0.0, velocity), np.where(at_limit, 0.0, acceleration)

    def track(
        self,
        position,
        velocity=None,
        acceleration=None,
        *,
        synchronize: bool = True,
        minimum_duration: float | None = None,
    ) -> ruckig.Result:
        """One cycle towards a target state (made feasible), reached no sooner than ``minimum_duration``
        from now, all joints together when ``synchronize``."""
        zeros = np.zeros(self.dofs)
        target = self.feasible(
            position, zeros if velocity is None else velocity, zeros if acceleration is None else acceleration
        )
        return self.track_feasible(*target, synchronize=synchronize, minimum_duration=minimum_duration)

    def track_feasible(
        self,
        position,
        velocity,
        acceleration,
        *,
        synchronize: bool = True,
        minimum_duration: float | None = None,
    ) -> ruckig.Result:
        """:meth:`track` for a target already made feasible (sequences of floats are fastest)."""
        inputs = self._input
        inputs.control_interface = ruckig.ControlInterface.Position
        inputs.synchronization = ruckig.Synchronization.Time if synchronize else ruckig.Synchronization.No
        inputs.minimum_duration = minimum_duration
        inputs.target_position = position
        inputs.target_velocity = velocity
        inputs.target_acceleration = acceleration
        return self._update()

    def brake(self) -> ruckig.Result:
        """One cycle of braking to rest within the limits (velocity control to zero); at rest already, the
        state stays as it is (what Ruckig would return, without asking it)."""
        if self.at_rest_exactly:
            return ruckig.Result.Finished
        inputs = self._input
        inputs.control_interface = ruckig.ControlInterface.Velocity
        inputs.synchronization = ruckig.Synchronization.No
        inputs.minimum_duration = None
        inputs.target_velocity = [0.0] * self.dofs
        inputs.target_acceleration = [0.0] * self.dofs
        return self._update()

    def _update(self) -> ruckig.Result:
        inputs, output = self._input, self._output
        try:
            result = self._otg.update(inputs, output)
        except ruckig.RuckigError:  # raised for inputs it rejects: the caller fails the motion (refusal)
            result = ruckig.Result.ErrorInvalidInput
        except ValueError:  # a trajectory longer than LONGEST
            result = ruckig.Result.ErrorExecutionTimeCalculation
        if result in WORKING:
            output.pass_to_input(inputs)
        elif self._arrived():
            # Ruckig refuses or cannot time a move that is only rounding (a speed of 1e-11 at the target
            # position, say): the target is reached already.
            inputs.current_position = list(inputs.target_position)
            inputs.current_velocity = list(inputs.target_velocity)
            inputs.current_acceleration = list(inputs.target_acceleration)
            return ruckig.Result.Finished
        return result

    def _arrived(self) -> bool:
        """Whether a position target is the commanded state but for rounding (:data:`ARRIVED`)."""
        inputs = self._input
        if inputs.control_interface != ruckig.ControlInterface.Position:
            return False
        pairs = (
            (inputs.current_position, inputs.target_position),
            (inputs.current_velocity, inputs.target_velocity),
            (inputs.current_acceleration, inputs.target_acceleration),
        )
        return all(
            abs(now - wanted) <= ARRIVED
            for current, target in pairs
            for now, wanted in zip(current, target, strict=True)
        )

    def refusal(self, joints) -> str:
        """Why Ruckig refused the last update (named by ``joints``), found by checking its input against the
        range and the limits: the first joint whose input breaks one, with its numbers, and what to change."""
        inputs = self._input
        current = self.state()
        targets = ()
        if inputs.control_interface == ruckig.ControlInterface.Position:
            targets = tuple(
                np.array(values, float)
                for values in (inputs.target_position, inputs.target_velocity, inputs.target_acceleration)
            )
        kinds = ("position", "velocity", "acceleration")
        states = [(f"target {kind}", values) for kind, values in zip(kinds, targets, strict=False)]
        states += [(f"current {kind}", values) for kind, values in zip(kinds, current, strict=True)]
        # The targets first: Ruckig brings a current state beyond the limits back, it refuses such targets.
        for what, values in states:
            change = "the motion's target" if what.startswith("target") else "the arm's commanded state"
            broken = np.flatnonzero(~np.isfinite(values))
            if broken.size:
                k = int(broken[0])
                return f"joint {joints[k]}'s {what} is {values[k]} (not a number): {change} is broken"
        limits = {"velocity": self.max_velocity, "acceleration": self.max_acceleration}
        for what, values in states:
            change = "the motion's target" if what.startswith("target") else "the arm's commanded state"
            kind = what.split()[1]
            if kind == "position":
                outside = np.maximum(self.lower - values, values - self.upper)
                k = int(outside.argmax())
                if outside[k] > 1e-9:
                    return (
                        f"joint {joints[k]}'s {what} {values[k]:.4g} is outside its range "
                        f"[{self.lower[k]:.4g}, {self.upper[k]:.4g}]: {change} is wrong"
                    )
                continue
            over = np.abs(values) / limits[kind]
            k = int(over.argmax())
            if over[k] > 1 + 1e-9:
                return (
                    f"joint {joints[k]}'s {what} {values[k]:.4g} is beyond its limit {limits[kind][k]:.4g}: "
                    f"{change} or the robot description's limits are wrong"
                )
        # Nothing out of bounds: the limits make the move too long for Ruckig (e.g. given in wrong units).
        distance = np.abs(targets[0] - current[0]) if targets else np.zeros(self.dofs)
        lasts = distance / self.max_velocity + np.abs(current[1]) / self.max_acceleration
        k = int(lasts.argmax())
        return (
            f"joint {joints[k]}'s limits (velocity {self.max_velocity[k]:.4g}, acceleration "
            f"{self.max_acceleration[k]:.4g}, jerk {self.max_jerk[k]:.4g}; rad or m, per s, s^2, s^3) make "
            f"its move of {distance[k]:.4g} last at least {lasts[k]:.4g} s (Ruckig plans at most "
            f"{LONGEST:g} s): check the limits in the robot's description"
        )
