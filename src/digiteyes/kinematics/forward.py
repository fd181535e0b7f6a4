"""Forward kinematics of a :class:`KinematicModel` for one state or a batch of states.

``forward_kinematics(model, q)`` returns a :class:`Kinematics` holding ``T_world_frame``
and ``T_world_shape`` for every row, evaluated level by level over the tree with batched
matrix products (all chains and all states at once; DESIGN.md Sec. 8).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np

from digiteyes.errors import StateError
from digiteyes.kinematics._kernels import fk_kernel
from digiteyes.kinematics.model import KinematicModel


def dh_transform(theta, d, a, alpha) -> np.ndarray:
    """Standard DH transform ``Rot_z(theta) Trans_z(d) Trans_x(a) Rot_x(alpha)`` (thesis
    eq. 2.2); arguments broadcast, result shape (..., 4, 4). Angles in radians, mm."""
    theta, d, a, alpha = np.broadcast_arrays(*(np.asarray(x, dtype=float)
                                               for x in (theta, d, a, alpha)))
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    out = np.zeros((*theta.shape, 4, 4))
    out[..., 0, 0], out[..., 0, 1], out[..., 0, 2], out[..., 0, 3] = ct, -st * ca, st * sa, a * ct
    out[..., 1, 0], out[..., 1, 1], out[..., 1, 2], out[..., 1, 3] = st, ct * ca, -ct * sa, a * st
    out[..., 2, 1], out[..., 2, 2], out[..., 2, 3] = sa, ca, d
    out[..., 3, 3] = 1.0
    return out


@dataclass
class Kinematics:
    """Per-state results of forward kinematics (pinocchio's ``Data``), world frame, mm.

    ``T_world_frame[n, r]`` is the pose of row r's frame, ``T_world_shape[n, r]`` that of its
    shape frame (frame r followed by ``Rot_z(theta_r)``, thesis eq. 2.4); shape (N, F, 4, 4).
    ``q`` is the (N, n_q) batch that produced them; ``batched`` says whether the caller
    passed a batch, so helpers can return matching shapes.
    """

    model: KinematicModel
    q: np.ndarray
    T_world_shape: np.ndarray
    batched: bool

    @cached_property
    def T_world_frame(self) -> np.ndarray:
        """Row frames (N, F, 4, 4): each shape frame turned back by ``Rot_z(-theta_r)``.

        Computed on first use: the maths (Jacobians included) only needs the shape frames,
        whose z axes and origins are those of the row frames.
        """
        model = self.model
        theta = np.broadcast_to(model.theta, (len(self.q), model.n_frames)).copy()
        joints = model.theta_state >= 0
        theta[:, joints] += self.q[:, model.theta_state[joints]]
        c, s = np.cos(theta)[..., None], np.sin(theta)[..., None]
        frame = self.T_world_shape.copy()
        x_axis, y_axis = self.T_world_shape[..., :3, 0], self.T_world_shape[..., :3, 1]
        frame[..., :3, 0] = x_axis * c - y_axis * s
        frame[..., :3, 1] = x_axis * s + y_axis * c
        return frame

    def _out(self, array: np.ndarray) -> np.ndarray:
        return array if self.batched else array[0]

    def link_segments(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Axis segments of the cylinder links: (start, end) in world mm, and link indices.

        Shapes (N, L, 3), (N, L, 3), (L,) (without N for a single state). A link runs from
        its shape-frame origin along the shape x axis for its length ``a``.
        """
        idx = np.array([i for i, link in enumerate(self.model.links) if link.kind == "link"])
        rows = np.array([self.model.links[i].row for i in idx], dtype=int)
        lengths = np.array([self.model.links[i].length for i in idx])
        shape = self.T_world_shape[:, rows]
        start = shape[..., :3, 3]
        end = start + shape[..., :3, 0] * lengths[:, None]
        return self._out(start), self._out(end), idx

    def tip_centres(self) -> tuple[np.ndarray, np.ndarray]:
        """Centres of the tip spheres in world mm, (N, T, 3), and their link indices (T,)."""
        idx = np.array([i for i, link in enumerate(self.model.links) if link.kind == "tip"])
        rows = np.array([self.model.links[i].row for i in idx], dtype=int)
        return self._out(self.T_world_shape[:, rows][..., :3, 3]), idx

    def points(self, rows: np.ndarray, p_shape: np.ndarray) -> np.ndarray:
        """World positions (N, P, 3) of points given in the shape frames of ``rows``.

        ``p_shape`` is (P, 3) in mm, one point per entry of ``rows``.
        """
        T = self.T_world_shape[:, np.asarray(rows, dtype=int)]
        p = np.einsum("npij,pj->npi", T[..., :3, :3], np.asarray(p_shape, dtype=float))
        return self._out(p + T[..., :3, 3])


def as_state_batch(model: KinematicModel, q: np.ndarray) -> tuple[np.ndarray, bool]:
    """Return ``q`` as an (N, n_q) float array and whether it was a batch.

    Raises :class:`StateError` for a wrong size or non-finite values.
    """
    if not isinstance(model, KinematicModel):
        raise StateError(f"model must be a KinematicModel, got {type(model).__name__}")
    try:
        q = np.asarray(q, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise StateError(f"state q must be an array of numbers, got {type(q).__name__}"
                         ) from None
    batched = q.ndim == 2
    if q.ndim not in (1, 2) or q.shape[-1] != model.n_q:
        raise StateError(
            f"model {model.name!r} needs states of size {model.n_q} (or batches (N, "
            f"{model.n_q})); got shape {q.shape}"
        )
    q2 = np.ascontiguousarray(q.reshape(len(q) if batched else 1, model.n_q))
    if not np.isfinite(q2.sum()) and not np.isfinite(q2).all():
        bad = np.argwhere(~np.isfinite(q2))[0]
        raise StateError(f"state q{bad[1]} ({model.state_names[bad[1]]}) is not finite")
    return q2, batched


def forward_kinematics(model: KinematicModel, q: np.ndarray) -> Kinematics:
    """Poses of every frame and shape frame for a state (n_q,) or a batch (N, n_q).

    The root pose is the spatial transform of the base states (quaternion normalised on
    the fly, thesis Sec. 2.2.1) or the identity; every other frame is its parent frame
    times the parent row's DH transform (thesis eq. 2.2). Raises
    :class:`~digiteyes.errors.StateError` for a wrong size or non-finite values.
    """
    Q, batched = as_state_batch(model, q)
    Q = np.require(Q, requirements=("C", "W"))  # one kernel specialisation, not a read-only one
    if model.base_state is not None:
        k = model.base_state
        if not np.all(np.abs(Q[:, k:k + 4]).max(axis=1) > 1e-150):
            raise StateError(f"the base quaternion q{k}..q{k + 3} is zero: it gives no "
                             "rotation")
    shape = np.empty((len(Q), model.n_frames, 4, 4))
    fk_kernel(Q, *fk_tables(model), shape)
    return Kinematics(model, Q, shape, batched)


@lru_cache(maxsize=64)
def fk_tables(model: KinematicModel) -> tuple:
    """What :func:`~digiteyes.kinematics._kernels.fk_kernel` needs from ``model``, in its
    argument order after the states: ``theta, d, a, cos_alpha, sin_alpha, theta_state,
    d_state, order, parent, base_state``."""
    return (model.theta, model.d, model.a, model.cos_alpha, model.sin_alpha,
            model.theta_state, model.d_state, model.order, model.parent,
            -1 if model.base_state is None else model.base_state)
