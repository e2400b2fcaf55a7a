"""Unit quaternions in (w, x, y, z) order, vectorised over leading axes.

Conventions (as MuJoCo's): ``multiply(p, q)`` is the Hamilton product p * q, a rotation q followed by p when
both act on vectors in the world frame; ``rotation_vector(q)`` is 2 log(q) = angle * axis with the angle in
[0, pi] (q and -q are the same rotation); ``from_rotation_vector(v)`` is its inverse exp(v / 2).
"""

from __future__ import annotations

import numpy as np

from besman.core.errors import InputError
from besman.core.validation import finite_array


def normalized(name: str, q) -> np.ndarray:
    """``q`` (..., 4) scaled to unit norm; a ``ValueError`` for NaN, a wrong shape or a zero norm."""
    q = finite_array(name, q)
    if q.shape[-1:] != (4,):
        raise InputError(f"{name} must be quaternions (w, x, y, z) with 4 entries, got shape {q.shape}")
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(norm < 1e-12):
        raise InputError(f"{name} has a zero-norm quaternion")
    return q / norm


def multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p * q."""
    pw, px, py, pz = np.moveaxis(p, -1, 0)
    qw, qx, qy, qz = np.moveaxis(q, -1, 0)
    return np.stack(
        [
            pw * qw - px * qx - py * qy - pz * qz,
            pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
        ],
        axis=-1,
    )


def conjugate(q: np.ndarray) -> np.ndarray:
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def rotation_vector(q: np.ndarray) -> np.ndarray:
    """2 log(q): the rotation's axis times its angle in [0, pi]."""
    q = np.where(q[..., :1] < 0.0, -q, q)
    vector = q[..., 1:]
    sine = np.linalg.norm(vector, axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(sine, q[..., :1])
    # angle / sin(angle / 2) -> 2 as the angle -> 0.
    factor = np.where(sine > 1e-12, angle / np.where(sine > 1e-12, sine, 1.0), 2.0)
    return factor * vector


def from_rotation_vector(v: np.ndarray) -> np.ndarray:
    """exp(v / 2): the unit quaternion of a rotation by |v| about v / |v|."""
    v = np.asarray(v, dtype=float)
    angle = np.linalg.norm(v, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(angle / 2) / angle -> 1/2 as the angle -> 0.
    factor = np.where(angle > 1e-12, np.sin(half) / np.where(angle > 1e-12, angle, 1.0), 0.5)
    return np.concatenate([np.cos(half), factor * v], axis=-1)


def from_matrix(matrix) -> np.ndarray:
    """Unit quaternions (..., 4) of rotation matrices (..., 3, 3), with w >= 0 (Shepperd 1978: the largest of
    the four squared components is found first and the others divided by it, which is stable everywhere)."""
    m = np.asarray(matrix, dtype=float)
    trace = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]
    # 4 w^2, 4 x^2, 4 y^2, 4 z^2 (each >= 0 for a rotation), and the off-diagonal sums and differences.
    squares = np.stack(
        [
            1.0 + trace,
            1.0 + 2.0 * m[..., 0, 0] - trace,
            1.0 + 2.0 * m[..., 1, 1] - trace,
            1.0 + 2.0 * m[..., 2, 2] - trace,
        ],
        axis=-1,
    )
    zy, yz = m[..., 2, 1], m[..., 1, 2]
    xz, zx = m[..., 0, 2], m[..., 2, 0]
    yx, xy = m[..., 1, 0], m[..., 0, 1]
    # Row k: 4 q_k times each of (w, x, y, z); the row of the largest component is divided by 4 q_k.
    products = np.stack(
        [
            np.stack([squares[..., 0], zy - yz, xz - zx, yx - xy], axis=-1),
            np.stack([zy - yz, squares[..., 1], xy + yx, xz + zx], axis=-1),
            np.stack([xz - zx, xy + yx, squares[..., 2], yz + zy], axis=-1),
            np.stack([yx - xy, xz + zx, yz + zy, squares[..., 3]], axis=-1),
        ],
        axis=-2,
    )
    best = np.argmax(squares, axis=-1)[..., None, None]
    row = np.take_along_axis(products, np.broadcast_to(best, (*best.shape[:-1], 4)), axis=-2)[..., 0, :]
    q = row / (2.0 * np.sqrt(np.take_along_axis(squares, best[..., 0], axis=-1)))
    return np.where(q[..., :1] < 0.0, -q, q)


def make_continuous(q: np.ndarray) -> np.ndarray:
    """Flips signs along the first axis so that consecutive quaternions are in the same hemisphere."""
    q = np.array(q, dtype=float)
    flips = np.cumsum(np.sum(q[1:] * q[:-1], axis=-1) < 0.0) % 2
    q[1:][flips == 1] *= -1.0
    return q


def mean(quaternions: np.ndarray) -> np.ndarray:
    """The average rotation (Markley et al. 2007): the principal eigenvector of sum q q^T."""
    _, vectors = np.linalg.eigh(np.einsum("ni,nj->ij", quaternions, quaternions))
    average = vectors[:, -1]
    return average if average[0] >= 0 else -average
