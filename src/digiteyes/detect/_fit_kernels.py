"""The keypoint fit's 2D terms in one compiled call (numba).

Per residual evaluation :class:`~digiteyes.detect.model_fit.KeypointFitProblem` needs the
forward kinematics of one state, the 21 keypoints with their point Jacobians (thesis eq.
2.16) and, per camera, their projections chained with those Jacobians (thesis eq. 2.6 and
2.17). Each step is compiled already, but called one by one from Python with the arrays
between them built by numpy they cost about 60 us an evaluation, most of it call overhead
(docs/keypoint-tracker.md, "The fit's 2D terms in one compiled call"); this kernel runs
them back to back.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from digiteyes.camera.camera import project_kernel
from digiteyes.kinematics.forward import fk_kernel
from digiteyes.kinematics.jacobian import jacobian_kernel


@njit(cache=True)
def keypoint_terms_kernel(Q, fk_tables, jac_tables, rows, p_shape, cameras, keypoints,
                          weights, scale, jacobian, shape, p_world, Jp, r,
                          J):  # pragma: no cover - compiled
    """Fill the 2D keypoint terms of the fit for the state ``Q`` (1, n_q).

    ``fk_tables`` and ``jac_tables`` are the model's arguments of the forward kinematics'
    and the point Jacobian's kernels (:func:`~digiteyes.kinematics.forward.fk_tables`,
    :func:`~digiteyes.kinematics.jacobian.jacobian_tables` in the tangent form);
    ``cameras`` (C, :data:`~digiteyes.camera.camera.PROJECTION_PARAMS`) the
    :attr:`~digiteyes.camera.Camera.projection_params` of each camera, ``keypoints``
    (C, P, 2) px and ``weights`` (C, P) per keypoint (confidence over
    sigma). Outputs: ``shape`` (1, F, 4, 4) shape frames, ``p_world`` (1, P, 3) and ``Jp``
    (1, P, 3, n_v) the unscaled keypoints (mm) and their Jacobian, ``r`` (C * 2P,) the
    weighted residuals ``w (pi(s p) - u)`` and, when ``jacobian``, ``J`` (C * 2P, n_v + 1)
    their Jacobian in the step and, last column, the scale ``s``.
    """
    theta0, d0, a, cos_alpha, sin_alpha, theta_state, d_state, order, parent, base = fk_tables
    moved, joint_row, jac_theta_state, jac_base, root, col_of_q, quaternion_form = jac_tables
    Jp[:] = 0.0
    fk_kernel(Q, theta0, d0, a, cos_alpha, sin_alpha, theta_state, d_state, order, parent,
              base, shape)
    jacobian_kernel(shape, Q, rows, p_shape, moved, joint_row, jac_theta_state, jac_base,
                    root, col_of_q, quaternion_form, p_world, Jp)
    n_points = rows.shape[0]
    n_v = Jp.shape[3]
    scaled = scale * p_world[0]
    pixels = np.empty((n_points, 2))
    dpix = np.empty((n_points, 2, 3))
    for c in range(cameras.shape[0]):
        project_kernel(cameras[c], scaled, pixels, dpix, jacobian)
        for k in range(n_points):
            w = weights[c, k]
            for i in range(2):
                row = c * 2 * n_points + 2 * k + i
                r[row] = (pixels[k, i] - keypoints[c, k, i]) * w
                if not jacobian:
                    continue
                d0_, d1_, d2_ = dpix[k, i, 0] * w, dpix[k, i, 1] * w, dpix[k, i, 2] * w
                for col in range(n_v):
                    J[row, col] = scale * (d0_ * Jp[0, k, 0, col] + d1_ * Jp[0, k, 1, col]
                                           + d2_ * Jp[0, k, 2, col])
                J[row, n_v] = (d0_ * p_world[0, k, 0] + d1_ * p_world[0, k, 1]
                               + d2_ * p_world[0, k, 2])
