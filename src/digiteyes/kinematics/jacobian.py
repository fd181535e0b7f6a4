"""Point Jacobians of the kinematic tree (thesis eq. 2.14-2.16, report eq. 8-10).

For a point attached to the shape frame of row ``r`` the columns are

* revolute state of row j:   ``n_j x (p - o_j)``  (thesis eq. 2.16, report eq. 8), with
  ``n_j`` the world z axis of frame j and ``o_j`` its origin;
* prismatic state of row j:  ``n_j``;
* base translation:          the identity (report eq. 9, world frame);
* base rotation, tangent form (default): a rotation step ``delta`` (3-vector, radians)
  turns the palm about its origin in the world frame, ``R <- exp([delta]x) R``, so the
  column for ``delta_k`` is ``e_k x (p - t)``;
* base rotation, quaternion form (thesis Sec. 2.2.1, report eq. 10): the derivative with
  respect to each raw quaternion number of the normalised rotation ``R(q / |q|)``,
  ``omega_j x (p - t)`` with ``omega = G(q) dq`` (:func:`quaternion_rate_matrix`).

Columns of states that do not move the point are zero.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Literal

import numpy as np

from digiteyes.kinematics._kernels import jacobian_kernel
from digiteyes.kinematics.forward import Kinematics
from digiteyes.kinematics.model import KinematicModel
from digiteyes.kinematics.step_form import StepForm

JacobianForm = StepForm | Literal["tangent", "quaternion"]


@lru_cache(maxsize=64)
def jacobian_tables(model: KinematicModel, form: JacobianForm) -> tuple:
    """What :func:`~digiteyes.kinematics._kernels.jacobian_kernel` needs from ``model``, in
    its argument order: ``shape_moved_by, joint_row, theta_state, base_state, root,
    col_of_q, quaternion_form``. ``col_of_q`` maps each state number to its Jacobian
    column (``n_q`` columns in the quaternion form, ``n_v`` in the tangent form)."""
    quaternion_form = StepForm.parse(form) is StepForm.QUATERNION
    col_of_q = np.arange(model.n_q) if quaternion_form else model.q_to_v
    return (model.shape_moved_by, model.joint_row, model.theta_state,
            -1 if model.base_state is None else model.base_state, model.root,
            np.ascontiguousarray(col_of_q, dtype=np.int64), quaternion_form)


def point_jacobian(
    kin: Kinematics,
    rows: np.ndarray,
    p_shape: np.ndarray,
    form: JacobianForm = "tangent",
) -> tuple[np.ndarray, np.ndarray]:
    """World positions and Jacobians of points fixed in shape frames.

    Parameters
    ----------
    kin : forward kinematics of one state or a batch.
    rows : (P,) row index of the shape frame each point is fixed in.
    p_shape : (P, 3) points in those shape frames, mm.
    form : ``"tangent"`` gives (..., P, 3, n_v) columns for the tangent step of
        :func:`~digiteyes.kinematics.state.integrate`; ``"quaternion"`` gives
        (..., P, 3, n_q) columns for the raw state numbers (thesis form).

    Returns
    -------
    p_world : (N, P, 3) or (P, 3), mm.
    J : (N, P, 3, n) or (P, 3, n); units mm per radian (revolute, rotation) or mm/mm.
    """
    form = StepForm.parse(form)
    rows = np.ascontiguousarray(rows, dtype=np.int64)
    p_shape = np.ascontiguousarray(p_shape, dtype=float).reshape(len(rows), 3)
    n = len(kin.q)
    tables = jacobian_tables(kin.model, form)
    p_world = np.empty((n, len(rows), 3))
    n_cols = form.n_columns(kin.model)
    J = np.zeros((n, len(rows), 3, n_cols))
    jacobian_kernel(kin.T_world_shape, kin.q, rows, p_shape, *tables, p_world, J)
    if not kin.batched:
        return p_world[0], J[0]
    return p_world, J
