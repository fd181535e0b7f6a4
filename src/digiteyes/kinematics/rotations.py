"""Rotations: unit quaternions (w, x, y, z), rotation matrices, the exponential map.

All functions take a single value or a batch with leading dimensions and return the same.
"""

from __future__ import annotations

import numpy as np


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix ``[v]x`` with ``[v]x @ u == cross(v, u)``; shape (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    out = np.zeros((*v.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def matrix_from_quaternion(quat: np.ndarray) -> np.ndarray:
    """Rotation matrix of a quaternion (w, x, y, z), normalised first (thesis Sec. 2.2.1).

    Including the normalisation in the map is the thesis's 4-parameter form: any non-zero
    quaternion gives a rotation, and scaling it changes nothing.
    """
    q = np.asarray(quat, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty((*q.shape[:-1], 3, 3))
    out[..., 0, 0] = 1 - 2 * (y * y + z * z)
    out[..., 0, 1] = 2 * (x * y - w * z)
    out[..., 0, 2] = 2 * (x * z + w * y)
    out[..., 1, 0] = 2 * (x * y + w * z)
    out[..., 1, 1] = 1 - 2 * (x * x + z * z)
    out[..., 1, 2] = 2 * (y * z - w * x)
    out[..., 2, 0] = 2 * (x * z - w * y)
    out[..., 2, 1] = 2 * (y * z + w * x)
    out[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return out


def quaternion_from_matrix(matrix: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) with w >= 0 of a rotation matrix (Shepperd's method)."""
    m = np.asarray(matrix, dtype=float)
    batch = m.shape[:-2]
    m = m.reshape(-1, 3, 3)
    trace = np.trace(m, axis1=1, axis2=2)
    candidates = np.stack(
        [
            np.stack([1 + trace, m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0],
                      m[:, 1, 0] - m[:, 0, 1]], axis=-1),
            np.stack([m[:, 2, 1] - m[:, 1, 2], 1 + 2 * m[:, 0, 0] - trace,
                      m[:, 0, 1] + m[:, 1, 0], m[:, 0, 2] + m[:, 2, 0]], axis=-1),
            np.stack([m[:, 0, 2] - m[:, 2, 0], m[:, 0, 1] + m[:, 1, 0],
                      1 + 2 * m[:, 1, 1] - trace, m[:, 1, 2] + m[:, 2, 1]], axis=-1),
            np.stack([m[:, 1, 0] - m[:, 0, 1], m[:, 0, 2] + m[:, 2, 0],
                      m[:, 1, 2] + m[:, 2, 1], 1 + 2 * m[:, 2, 2] - trace], axis=-1),
        ],
        axis=1,
    )
    diag = np.stack([trace, m[:, 0, 0], m[:, 1, 1], m[:, 2, 2]], axis=-1)
    best = np.argmax(diag, axis=-1)
    q = candidates[np.arange(len(m)), best]
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return q.reshape(*batch, 4)


def quaternion_multiply(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Hamilton product ``q1 * q2`` of (w, x, y, z) quaternions."""
    w1, x1, y1, z1 = np.moveaxis(np.asarray(q1, dtype=float), -1, 0)
    w2, x2, y2, z2 = np.moveaxis(np.asarray(q2, dtype=float), -1, 0)
    return np.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        axis=-1,
    )


def quaternion_from_rotvec(rotvec: np.ndarray) -> np.ndarray:
    """Exponential map: rotation vector (axis * angle, radians) to unit quaternion."""
    r = np.asarray(rotvec, dtype=float)
    angle = np.linalg.norm(r, axis=-1, keepdims=True)
    half = 0.5 * angle
    # sin(x/2)/x, with its Taylor series near zero.
    small = angle < 1e-8
    safe = np.where(small, 1.0, angle)
    scale = np.where(small, 0.5 - angle**2 / 48.0, np.sin(half) / safe)
    return np.concatenate([np.cos(half), r * scale], axis=-1)


def rotvec_from_quaternion(quat: np.ndarray) -> np.ndarray:
    """Logarithm map: unit quaternion to rotation vector with angle in [0, pi]."""
    q = np.asarray(quat, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    q = q * np.where(q[..., :1] < 0, -1.0, 1.0)
    vec_norm = np.linalg.norm(q[..., 1:], axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(vec_norm, q[..., :1])
    small = vec_norm < 1e-12
    scale = np.where(small, 2.0, angle / np.where(small, 1.0, vec_norm))
    return q[..., 1:] * scale


def quaternion_rate_matrix(quat: np.ndarray) -> np.ndarray:
    """Map ``G`` with world angular velocity ``omega = G @ dq`` for the normalised form.

    For the rotation ``R(q / |q|)`` (thesis Sec. 2.2.1, report eq. 12) a change ``dq`` of
    the four raw parameters turns the world frame by ``omega = 2 Im(dq * conj(q)) / |q|^2``;
    the part of ``dq`` along ``q`` only rescales and turns nothing. Shape (..., 3, 4).
    """
    q = np.asarray(quat, dtype=float)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    scale = 2.0 / np.sum(q * q, axis=-1)
    g = np.stack(
        [
            np.stack([-x, w, -z, y], axis=-1),
            np.stack([-y, z, w, -x], axis=-1),
            np.stack([-z, -y, x, w], axis=-1),
        ],
        axis=-2,
    )
    return g * scale[..., None, None]


def quaternion_angle(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Geodesic angle (radians, in [0, pi]) between the rotations of two quaternions.

    Quaternions (w, x, y, z), any norm, batched over leading dimensions. Sign-invariant:
    ``q`` and ``-q`` are the same rotation. Computed as ``2 atan2(|v|, |w|)`` of the relative
    quaternion ``conj(q1) q2 = (w, v)``, accurate for small and large angles alike.
    """
    q1 = np.asarray(q1, dtype=float)
    q2 = np.asarray(q2, dtype=float)
    q1 = q1 / np.linalg.norm(q1, axis=-1, keepdims=True)
    q2 = q2 / np.linalg.norm(q2, axis=-1, keepdims=True)
    w1, v1 = q1[..., 0], q1[..., 1:]
    w2, v2 = q2[..., 0], q2[..., 1:]
    w = w1 * w2 + np.sum(v1 * v2, axis=-1)
    v = w1[..., None] * v2 - w2[..., None] * v1 - np.cross(v1, v2)
    return 2.0 * np.arctan2(np.linalg.norm(v, axis=-1), np.abs(w))


def matrix_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Geodesic angle (radians, in [0, pi]) between rotation matrices ``a`` and ``b``
    (..., 3, 3), from ``||a - b||_F = 2 sqrt(2) sin(angle / 2)``: accurate near zero,
    where ``arccos((trace(a^T b) - 1) / 2)`` loses half the digits."""
    chord = np.linalg.norm(np.asarray(a, dtype=float) - np.asarray(b, dtype=float),
                           axis=(-2, -1)) / (2.0 * np.sqrt(2.0))
    return 2.0 * np.arcsin(np.clip(chord, 0.0, 1.0))


def wrap_angle(angle: np.ndarray | float) -> np.ndarray:
    """Angles wrapped into [-pi, pi) (radians)."""
    return (np.asarray(angle, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi
