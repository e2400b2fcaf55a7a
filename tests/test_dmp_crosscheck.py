"""Cross-check against the peer library movement-primitives (its compiled Euler integration at 1 ms).

Both libraries imitate the same demonstrations with equivalent settings (10 weights per dimension,
alpha_y = 25, beta_y = 6.25, phase 0.01 at the end, overlap 0.8) and their trajectories are compared.
Differences come from the peer's side: it estimates derivatives by backward differences (assuming a zero
start velocity), integrates with explicit Euler at 1 ms, and (for CartesianDMP) has no goal velocity.
The demonstrations therefore start at rest, and the Cartesian one also ends at rest.
"""

import numpy as np
import pytest

from besman.skills import DMP, CartesianDMP
from besman.skills import quaternion as quat

movement_primitives = pytest.importorskip(
    "movement_primitives.dmp", reason="dev dependency movement-primitives"
)

TIMES = np.linspace(0.0, 1.0, 1001)  # 1 ms, the peer's integration step
S = TIMES
MINIMUM_JERK = 10 * S**3 - 15 * S**4 + 6 * S**5


def test_joint_dmp_agrees_with_dmp_with_final_velocity():
    demonstration = np.column_stack(
        [
            0.5 * MINIMUM_JERK + 0.1 * (1 - np.cos(2 * np.pi * S)),
            -0.3 * MINIMUM_JERK + 0.2 * np.sin(np.pi * S) ** 2,
            0.4 * S**3,  # ends moving: a goal velocity of 1.2 / s
        ]
    )
    peer = movement_primitives.DMPWithFinalVelocity(3, execution_time=1.0, dt=0.001, n_weights_per_dim=10)
    peer.imitate(TIMES, demonstration)
    _, peer_positions = peer.open_loop()
    ours = DMP(3, dt=0.001).imitate(TIMES, demonstration).trajectory()
    amplitude = np.ptp(demonstration, axis=0)
    assert np.all(np.abs(ours.positions - peer_positions).max(axis=0) < 0.01 * amplitude)


def test_cartesian_dmp_agrees_with_cartesian_dmp():
    positions = np.column_stack(
        [0.5 * MINIMUM_JERK + 0.1 * (1 - np.cos(2 * np.pi * S)), -0.3 * MINIMUM_JERK, 0.3 * MINIMUM_JERK]
    )
    rotations = np.column_stack([0.8 * MINIMUM_JERK, 0.3 * np.sin(np.pi * S) ** 2, -0.5 * MINIMUM_JERK])
    orientations = quat.from_rotation_vector(rotations)
    peer = movement_primitives.CartesianDMP(execution_time=1.0, dt=0.001, n_weights_per_dim=10)
    peer.imitate(TIMES, np.hstack([positions, orientations]))
    _, peer_poses = peer.open_loop()
    ours = CartesianDMP(dt=0.001).imitate(TIMES, positions, orientations).trajectory()
    assert np.all(np.abs(ours.positions - peer_poses[:, :3]).max(axis=0) < 0.01 * np.ptp(positions, axis=0))
    turned = quat.rotation_vector(quat.multiply(ours.orientations, quat.conjugate(peer_poses[:, 3:])))
    assert np.linalg.norm(turned, axis=1).max() < 0.01 * np.linalg.norm(np.ptp(rotations, axis=0))
