"""Basis configurations and the linear manifolds between them (Huang Sec. 2, eq. 1).

A manifold ``L_ij`` is the segment from basis state ``b_i`` to ``b_j`` in PCA coordinates,
parameterised as in Huang eq. 4: ``X = s b_i + (1 - s) b_j`` with ``s`` in [0, 1] (``s = 1``
at ``b_i``). The paper's formula for ``s`` (Sec. 5.1) divides the dot product by
``||b_j - b_i||``; the projection needs the squared norm, which we use.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from digiteyes.kinematics import KinematicModel
from digiteyes.kinematics.anatomy import DIGITS, basis_configurations, digit_joint_angles
from digiteyes.smc._kernels import nearest_segment_kernel

DEG = np.pi / 180.0


def basis_names() -> tuple[str, ...]:
    """The 28 basis configurations (:func:`digiteyes.kinematics.anatomy.
    basis_configurations`): each digit (thumb, index, middle, ring, little) ``E`` (fully
    extended) or ``C`` (fully curled), without the four that hold the ring finger extended
    between two curled neighbours."""
    return tuple(basis_configurations())


def basis_joint_angles(joint_names: tuple[str, ...]) -> np.ndarray:
    """The basis configurations as joint-angle vectors (28, J), rad, for ``joint_names``
    (names a model lacks are skipped; joints no digit table sets stay 0)."""
    out = np.zeros((len(basis_names()), len(joint_names)))
    column = {name: j for j, name in enumerate(joint_names)}
    for b, name in enumerate(basis_names()):
        for digit, letter in zip(DIGITS, name, strict=True):
            for joint, value in digit_joint_angles(digit, letter == "E").items():
                if joint in column:
                    out[b, column[joint]] = value
    return out


def model_joint_names(model: KinematicModel) -> tuple[str, ...]:
    """Names of the model's finger joint states (every ``angle`` state), model order."""
    return tuple(n for n, k in zip(model.state_names, model.state_kinds, strict=True)
                 if k == "angle")


def manifold_pairs(n_basis: int) -> np.ndarray:
    """Index pairs (P, 2) ``(i, j)``, ``i < j``, of every manifold ``L_ij`` (eq. 1)."""
    i, j = np.triu_indices(n_basis, k=1)
    return np.stack([i, j], axis=1)


@dataclass(frozen=True)
class ManifoldProjection:
    """Projection of states onto their nearest manifold (Huang Sec. 5.1).

    Attributes
    ----------
    pair : (N,) index into the pairs of the nearest manifold.
    s : (N,) position on it, ``X~ = s b_i + (1 - s) b_j``, in [0, 1].
    projected : (N, D) the projected states ``X~``.
    distance : (N,) distance from each state to its manifold (PCA units).
    """

    pair: np.ndarray
    s: np.ndarray
    projected: np.ndarray
    distance: np.ndarray


def project_onto_manifolds(X: np.ndarray, basis: np.ndarray, pairs: np.ndarray
                           ) -> ManifoldProjection:
    """Project states ``X`` (N, D) onto the nearest segment ``b_i b_j`` of ``pairs``
    (compiled loop over all (state, manifold) pairs, O(N P D))."""
    X = np.ascontiguousarray(np.atleast_2d(np.asarray(X, dtype=float)))
    bi = np.ascontiguousarray(basis[pairs[:, 0]], dtype=float)
    d = np.ascontiguousarray(basis[pairs[:, 1]] - bi)
    best = np.empty(len(X), dtype=np.int64)
    t = np.empty(len(X))
    distance = np.empty(len(X))
    nearest_segment_kernel(X, bi, d, best, t, distance)
    projected = bi[best] + t[:, None] * d[best]
    return ManifoldProjection(best, 1.0 - t, projected, distance)
