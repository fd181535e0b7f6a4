"""Compiled inner loops of forward kinematics and point Jacobians (numba).

Profiling the vectorised numpy version showed Python call overhead, not arithmetic,
dominating a single hand state (about 350 us for ~40 small array operations, DESIGN.md
Sec. 8), so the tree walk is compiled. Each loop visits the rows in topological order
once per state; transforms are rigid, so only their 3x4 part is computed.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def fk_kernel(Q, theta0, d0, a, cos_alpha, sin_alpha, theta_state, d_state, order, parent,
              base_state, shape):  # pragma: no cover - compiled
    """Fill ``shape`` (N, F, 4, 4) with the shape-frame poses of the states ``Q`` (N, n_q).

    Row r's frame ``W`` is its parent's outgoing transform (or the base pose at the root);
    ``shape[n, r] = W Rot_z(theta_r)`` (thesis eq. 2.4), and the frames after row r are
    ``shape[n, r] Trans_z(d) Trans_x(a) Rot_x(alpha)`` (the rest of thesis eq. 2.2).
    Transforms are rigid, so only their 3x4 part is computed.
    """
    n_states = Q.shape[0]
    n_frames = theta0.shape[0]
    outgoing = np.empty((n_frames, 3, 4))
    W = np.empty((3, 4))
    for n in range(n_states):
        for idx in range(n_frames):
            r = order[idx]
            p = parent[r]
            if p < 0:
                if base_state >= 0:
                    w = Q[n, base_state]
                    x = Q[n, base_state + 1]
                    y = Q[n, base_state + 2]
                    z = Q[n, base_state + 3]
                    inv = 1.0 / (w * w + x * x + y * y + z * z)
                    W[0, 0] = 1.0 - 2.0 * (y * y + z * z) * inv
                    W[0, 1] = 2.0 * (x * y - w * z) * inv
                    W[0, 2] = 2.0 * (x * z + w * y) * inv
                    W[1, 0] = 2.0 * (x * y + w * z) * inv
                    W[1, 1] = 1.0 - 2.0 * (x * x + z * z) * inv
                    W[1, 2] = 2.0 * (y * z - w * x) * inv
                    W[2, 0] = 2.0 * (x * z - w * y) * inv
                    W[2, 1] = 2.0 * (y * z + w * x) * inv
                    W[2, 2] = 1.0 - 2.0 * (x * x + y * y) * inv
                    W[0, 3] = Q[n, base_state + 4]
                    W[1, 3] = Q[n, base_state + 5]
                    W[2, 3] = Q[n, base_state + 6]
                else:
                    for i in range(3):
                        for j in range(4):
                            W[i, j] = 1.0 if i == j else 0.0
            else:
                for i in range(3):
                    for j in range(4):
                        W[i, j] = outgoing[p, i, j]
            th = theta0[r]
            if theta_state[r] >= 0:
                th += Q[n, theta_state[r]]
            dd = d0[r]
            if d_state[r] >= 0:
                dd += Q[n, d_state[r]]
            c = np.cos(th)
            s = np.sin(th)
            ca = cos_alpha[r]
            sa = sin_alpha[r]
            S = shape[n, r]
            for i in range(3):
                xi = W[i, 0] * c + W[i, 1] * s
                yi = W[i, 1] * c - W[i, 0] * s
                zi = W[i, 2]
                S[i, 0] = xi
                S[i, 1] = yi
                S[i, 2] = zi
                S[i, 3] = W[i, 3]
                outgoing[r, i, 0] = xi
                outgoing[r, i, 1] = ca * yi + sa * zi
                outgoing[r, i, 2] = ca * zi - sa * yi
                outgoing[r, i, 3] = W[i, 3] + a[r] * xi + dd * zi
            S[3, 0] = 0.0
            S[3, 1] = 0.0
            S[3, 2] = 0.0
            S[3, 3] = 1.0


@njit(cache=True)
def jacobian_kernel(shape, q, rows, p_shape, moved, joint_row, theta_state, base_state,
                    root, col_of_q, quaternion_form, p_world, J):  # pragma: no cover - compiled
    """Fill ``p_world`` (N, P, 3) with the world positions of points ``p_shape`` (P, 3) fixed
    in the shape frames of ``rows``, and ``J`` (N, P, 3, n_cols) with their Jacobian columns
    (thesis eq. 2.16).

    Revolute: ``z_j x (p - o_j)``; prismatic: ``z_j``; base translation: identity; base
    rotation: ``e_k x (p - t)`` (tangent) or ``G(q)[:, k] x (p - t)`` (quaternion form,
    :func:`digiteyes.kinematics.rotations.quaternion_rate_matrix`).
    """
    n_states = shape.shape[0]
    n_points = rows.shape[0]
    n_q = joint_row.shape[0]
    G = np.zeros((3, 4))
    for n in range(n_states):
        if base_state >= 0 and quaternion_form:
            w = q[n, base_state]
            x = q[n, base_state + 1]
            y = q[n, base_state + 2]
            z = q[n, base_state + 3]
            k = 2.0 / (w * w + x * x + y * y + z * z)
            G[0, 0], G[0, 1], G[0, 2], G[0, 3] = -x * k, w * k, -z * k, y * k
            G[1, 0], G[1, 1], G[1, 2], G[1, 3] = -y * k, z * k, w * k, -x * k
            G[2, 0], G[2, 1], G[2, 2], G[2, 3] = -z * k, -y * k, x * k, w * k
        for p in range(n_points):
            T = shape[n, rows[p]]
            sx = p_shape[p, 0]
            sy = p_shape[p, 1]
            sz = p_shape[p, 2]
            px = T[0, 0] * sx + T[0, 1] * sy + T[0, 2] * sz + T[0, 3]
            py = T[1, 0] * sx + T[1, 1] * sy + T[1, 2] * sz + T[1, 3]
            pz = T[2, 0] * sx + T[2, 1] * sy + T[2, 2] * sz + T[2, 3]
            p_world[n, p, 0] = px
            p_world[n, p, 1] = py
            p_world[n, p, 2] = pz
            for s in range(n_q):
                jr = joint_row[s]
                if jr < 0 or not moved[rows[p], s]:
                    continue
                col = col_of_q[s]
                ax = shape[n, jr, 0, 2]
                ay = shape[n, jr, 1, 2]
                az = shape[n, jr, 2, 2]
                if theta_state[jr] == s:
                    rx = px - shape[n, jr, 0, 3]
                    ry = py - shape[n, jr, 1, 3]
                    rz = pz - shape[n, jr, 2, 3]
                    J[n, p, 0, col] = ay * rz - az * ry
                    J[n, p, 1, col] = az * rx - ax * rz
                    J[n, p, 2, col] = ax * ry - ay * rx
                else:
                    J[n, p, 0, col] = ax
                    J[n, p, 1, col] = ay
                    J[n, p, 2, col] = az
            if base_state >= 0:
                rx = px - shape[n, root, 0, 3]
                ry = py - shape[n, root, 1, 3]
                rz = pz - shape[n, root, 2, 3]
                k0 = base_state
                if quaternion_form:
                    for j in range(4):
                        ox = G[0, j]
                        oy = G[1, j]
                        oz = G[2, j]
                        J[n, p, 0, k0 + j] = oy * rz - oz * ry
                        J[n, p, 1, k0 + j] = oz * rx - ox * rz
                        J[n, p, 2, k0 + j] = ox * ry - oy * rx
                    t0 = k0 + 4
                else:
                    # columns e_x x r, e_y x r, e_z x r
                    J[n, p, 1, k0] = -rz
                    J[n, p, 2, k0] = ry
                    J[n, p, 0, k0 + 1] = rz
                    J[n, p, 2, k0 + 1] = -rx
                    J[n, p, 0, k0 + 2] = -ry
                    J[n, p, 1, k0 + 2] = rx
                    t0 = k0 + 3
                J[n, p, 0, t0] = 1.0
                J[n, p, 1, t0 + 1] = 1.0
                J[n, p, 2, t0 + 2] = 1.0


@njit(cache=True)
def integrate_kernel(q, dv, q_to_v, base_state, out):  # pragma: no cover - compiled
    """Retraction of the states ``q`` (N, n_q) by tangent steps ``dv`` (N, n_v) into ``out``.

    Numbers with a tangent index add; the base quaternion (w, x, y, z) is turned on the left
    by ``exp(dv_rot)`` (world frame) and renormalised.
    """
    n_states, n_q = q.shape
    for n in range(n_states):
        for i in range(n_q):
            j = q_to_v[i]
            out[n, i] = q[n, i] + dv[n, j] if j >= 0 else q[n, i]
        if base_state >= 0:
            k = base_state
            rx = dv[n, k]
            ry = dv[n, k + 1]
            rz = dv[n, k + 2]
            angle = np.sqrt(rx * rx + ry * ry + rz * rz)
            if angle < 1e-8:
                scale = 0.5 - angle * angle / 48.0  # sin(angle/2)/angle near zero
            else:
                scale = np.sin(0.5 * angle) / angle
            tw = np.cos(0.5 * angle)
            tx = rx * scale
            ty = ry * scale
            tz = rz * scale
            w = q[n, k]
            x = q[n, k + 1]
            y = q[n, k + 2]
            z = q[n, k + 3]
            nw = tw * w - tx * x - ty * y - tz * z
            nx = tw * x + tx * w + ty * z - tz * y
            ny = tw * y - tx * z + ty * w + tz * x
            nz = tw * z + tx * y - ty * x + tz * w
            inv = 1.0 / np.sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
            out[n, k] = nw * inv
            out[n, k + 1] = nx * inv
            out[n, k + 2] = ny * inv
            out[n, k + 3] = nz * inv


@njit(cache=True)
def difference_kernel(q0, q1, q_to_v, base_state, out):  # pragma: no cover - compiled
    """Tangent steps from the states ``q0`` to ``q1`` (N, n_q) into ``out`` (N, n_v), the
    inverse of :func:`integrate_kernel`: numbers with a tangent index subtract; the base
    rotation's step is the rotation vector of ``q1 * conj(q0)`` (both normalised, angle in
    [0, pi])."""
    n_states, n_q = q0.shape
    for n in range(n_states):
        for i in range(n_q):
            j = q_to_v[i]
            if j >= 0:
                out[n, j] = q1[n, i] - q0[n, i]
        if base_state >= 0:
            k = base_state
            w0 = q0[n, k]
            x0 = q0[n, k + 1]
            y0 = q0[n, k + 2]
            z0 = q0[n, k + 3]
            w1 = q1[n, k]
            x1 = q1[n, k + 1]
            y1 = q1[n, k + 2]
            z1 = q1[n, k + 3]
            w = w1 * w0 + x1 * x0 + y1 * y0 + z1 * z0  # q1 * conj(q0)
            x = -w1 * x0 + x1 * w0 - y1 * z0 + z1 * y0
            y = -w1 * y0 + x1 * z0 + y1 * w0 - z1 * x0
            z = -w1 * z0 - x1 * y0 + y1 * x0 + z1 * w0
            inv = 1.0 / np.sqrt(w * w + x * x + y * y + z * z)
            if w < 0.0:
                inv = -inv
            w *= inv
            x *= inv
            y *= inv
            z *= inv
            vector = np.sqrt(x * x + y * y + z * z)
            scale = 2.0 if vector < 1e-12 else 2.0 * np.arctan2(vector, w) / vector
            out[n, k] = x * scale
            out[n, k + 1] = y * scale
            out[n, k + 2] = z * scale
