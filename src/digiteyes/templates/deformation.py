"""The template deformation: template pixels to image pixels as a function of the state
(Rehg thesis eq. 2.9-2.11, 2.13-2.16).

A template pixel with coordinates ``(a, b)`` is a point fixed in its part's shape frame
(:mod:`digiteyes.occlusion.parts`); forward kinematics places it in the world and the
camera projects it, ``w = f(q, s)``. Its derivative with respect to a tangent step ``v``
of the state (:func:`digiteyes.kinematics.integrate`) factors as

    dw/dv = (dw/dp) (dp/dv),         dp/dv = omega x p + u,

where ``(omega, u)`` (6, n_v), the *twist* of the part, is the same for every point of
the part (a rigid body's velocity field). Thesis eq. 2.16's columns ``n_i x (p - o_i)``
are exactly of this form. The SSD residual ``I(f(q, s)) - T(s)`` (eq. 2.11) then has the
Jacobian row (eq. 2.13, 3.10)

    J = grad I^T (dw/dp) (dp/dv) = m^T [omega; u],     m = [p x a; a],  a = (dw/dp)^T grad I,

so a compiled loop accumulates the 6 x 6 matrix ``sum m m^T`` per part and the normal
equations follow as ``sum_k Tw_k^T H6_k Tw_k`` without forming the (P, n_v) Jacobian.
"""

from __future__ import annotations

import numpy as np

from digiteyes.kinematics import Kinematics, point_jacobian
from digiteyes.occlusion.parts import TemplatePart


def part_twists(parts: tuple[TemplatePart, ...], kin: Kinematics) -> np.ndarray:
    """Twists (K, 6, n_v) of the parts' shape frames: world velocity
    ``dp/dv = omega x p + u`` of any point ``p`` (world mm) fixed on part k, with
    ``omega = Tw[k, :3]`` (rad per unit step) and ``u = Tw[k, 3:]`` (mm per unit step).

    Read off :func:`~digiteyes.kinematics.point_jacobian` at the shape-frame origin and
    the three points one mm from it along the world axes.
    """
    T = kin.T_world_shape[0]
    rows = np.repeat([p.row for p in parts], 4)
    p_shape = np.zeros((len(parts), 4, 3))
    for k, part in enumerate(parts):
        p_shape[k, 1:] = T[part.row, :3, :3]  # rows: shape coordinates of world e_x, e_y, e_z
    _, J = point_jacobian(kin, rows, p_shape.reshape(-1, 3))
    J = J.reshape(len(parts), 4, 3, -1)
    origin = T[[p.row for p in parts], :3, 3]
    dx, dy, dz = J[:, 1] - J[:, 0], J[:, 2] - J[:, 0], J[:, 3] - J[:, 0]
    omega = np.stack([dy[:, 2], dz[:, 0], dx[:, 1]], axis=1)  # (K, 3, n_v)
    u = J[:, 0] - np.cross(omega, origin[:, :, None], axis=1)
    return np.ascontiguousarray(np.concatenate([omega, u], axis=1))
