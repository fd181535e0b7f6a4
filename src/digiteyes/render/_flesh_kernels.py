"""Compiled sphere tracing of the "flesh" hand: blended round cones and round boxes.

The surface is the zero set of one signed-distance field, the smooth union of its
primitives' exact distances taken one after another,

    f = smin(... smin(smin(d_0, d_1, k_1), d_2, k_2) ..., d_n, k_n),
    smin(a, b, k) = min(a, b) - k h^2 / 4,   h = max(k - |a - b|, 0) / k

(the quadratic polynomial smooth minimum; k = 0 is the plain union). The partial
derivatives of smin are h/2 and 1 - h/2 in some order, both in [0, 1] and summing to 1, so
f is 1-Lipschitz wherever every d_i is: stepping a ray by ``f(p) / |d|`` never passes the
surface (sphere tracing, Hart 1996).

Culling. Every primitive has a bounding sphere (its own bound grown by its blend width k)
and the pixel block that sphere projects into. A pixel's ray only evaluates the
primitives whose block holds the pixel and whose sphere the ray meets; the others are
further than k from every point of the ray, where their smin term is an exact min with a
larger value, so they cannot change the surface along that ray. The march starts where
the ray enters the first of those spheres and stops where it leaves the last.

Conventions as in :mod:`digiteyes.render._kernels` (camera frame, ray direction
(x, y, 1) or (0, 0, 1), ray parameter = camera depth). Parameters, one row of 17 numbers:

* round cone (kind 0): start a (3), end b (3), radius at a, radius at b;
* round box (kind 1): centre (3), three unit axes (3 x 3, axis after axis), inner half
  extents (3), rounding radius.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

ROUND_CONE, ROUND_BOX = 0, 1
N_PARAMS = 17
_EPS = 0.02  # mm: a ray has hit when the field is below this
_MAX_STEPS = 160
_GRAD_H = 0.05  # mm: step of the finite-difference normal
_RELAX = 1.5  # over-relaxation of the sphere-tracing steps
_FAST = {"nsz", "arcp", "contract", "afn", "reassoc"}  # fast maths that keeps inf and NaN


@njit(cache=True, fastmath=_FAST, error_model="numpy", inline="always")
def _round_cone(px, py, pz, P):  # pragma: no cover - compiled
    """Exact signed distance to the convex hull of the balls (a, ra) and (b, rb)."""
    bax, bay, baz = P[3] - P[0], P[4] - P[1], P[5] - P[2]
    l2 = bax * bax + bay * bay + baz * baz
    dr = P[6] - P[7]
    a2 = l2 - dr * dr
    pax, pay, paz = px - P[0], py - P[1], pz - P[2]
    y = pax * bax + pay * bay + paz * baz  # along the axis, scaled by l2
    z = y - l2
    wx, wy, wz = pax * l2 - bax * y, pay * l2 - bay * y, paz * l2 - baz * y
    x2 = wx * wx + wy * wy + wz * wz  # squared distance from the axis, scaled by l2^2
    y2 = y * y * l2
    z2 = z * z * l2
    k = math.copysign(1.0, dr) * dr * dr * x2
    if math.copysign(1.0, z) * a2 * z2 > k:
        return math.sqrt(x2 + z2) / l2 - P[7]
    if math.copysign(1.0, y) * a2 * y2 < k:
        return math.sqrt(x2 + y2) / l2 - P[6]
    return (math.sqrt(x2 * a2 / l2) + y * dr) / l2 - P[6]


@njit(cache=True, fastmath=_FAST, error_model="numpy", inline="always")
def _round_box(px, py, pz, P):  # pragma: no cover - compiled
    """Exact signed distance to a box of inner half extents P[12:15] grown by P[15]."""
    rx, ry, rz = px - P[0], py - P[1], pz - P[2]
    q0 = abs(rx * P[3] + ry * P[4] + rz * P[5]) - P[12]
    q1 = abs(rx * P[6] + ry * P[7] + rz * P[8]) - P[13]
    q2 = abs(rx * P[9] + ry * P[10] + rz * P[11]) - P[14]
    m0, m1, m2 = max(q0, 0.0), max(q1, 0.0), max(q2, 0.0)
    return math.sqrt(m0 * m0 + m1 * m1 + m2 * m2) + min(max(q0, max(q1, q2)), 0.0) - P[15]


@njit(cache=True, fastmath=_FAST, error_model="numpy", inline="always")
def _distance(kind, px, py, pz, P):  # pragma: no cover - compiled
    if kind == ROUND_CONE:
        return _round_cone(px, py, pz, P)
    return _round_box(px, py, pz, P)


@njit(cache=True, fastmath=_FAST, error_model="numpy", inline="always")
def _smin(a, b, k):  # pragma: no cover - compiled
    if k <= 0.0:
        return min(a, b)
    h = max(k - abs(a - b), 0.0) / k
    return min(a, b) - 0.25 * k * h * h


@njit(cache=True, fastmath=_FAST, error_model="numpy")
def _field(px, py, pz, kinds, params, blend, cand, n_cand):  # pragma: no cover - compiled
    """The blended field at p over the candidate primitives ``cand[:n_cand]``."""
    f = np.inf
    for j in range(n_cand):
        k = cand[j]
        f = _smin(f, _distance(kinds[k], px, py, pz, params[k]), blend[k])
    return f


@njit(cache=True, fastmath=_FAST, error_model="numpy")
def field_at(points, kinds, params, blend):  # pragma: no cover - compiled
    """(M,) blended field and (M,) nearest primitive at points (M, 3), all primitives."""
    n = kinds.shape[0]
    cand = np.arange(n)
    out = np.empty(points.shape[0])
    nearest = np.empty(points.shape[0], dtype=np.int64)
    for m in range(points.shape[0]):
        px, py, pz = points[m, 0], points[m, 1], points[m, 2]
        out[m] = _field(px, py, pz, kinds, params, blend, cand, n)
        best, arg = np.inf, -1
        for k in range(n):
            d = _distance(kinds[k], px, py, pz, params[k])
            if d < best:
                best, arg = d, k
        nearest[m] = arg
    return out, nearest


@njit(cache=True, fastmath=_FAST, error_model="numpy")
def distances_at(points, kinds, params):  # pragma: no cover - compiled
    """(M, P) signed distance from each point (M, 3) to each primitive, unblended."""
    out = np.empty((points.shape[0], kinds.shape[0]))
    for m in range(points.shape[0]):
        for k in range(kinds.shape[0]):
            out[m, k] = _distance(kinds[k], points[m, 0], points[m, 1], points[m, 2],
                                  params[k])
    return out


@njit(cache=True, fastmath=_FAST, error_model="numpy", inline="always")
def _sphere_span(ox, oy, oz, dx, dy, dz, S):  # pragma: no cover - compiled
    """Ray parameters where the ray is inside the bounding sphere S = (c, R), or (1, 0)."""
    px, py, pz = ox - S[0], oy - S[1], oz - S[2]
    dd = dx * dx + dy * dy + dz * dz
    b = dx * px + dy * py + dz * pz
    h = b * b - dd * (px * px + py * py + pz * pz - S[3] * S[3])
    if h < 0.0:
        return 1.0, 0.0
    root = math.sqrt(h)
    return (-b - root) / dd, (-b + root) / dd


@njit(cache=True, fastmath=_FAST, error_model="numpy", inline="always")
def _near_core(ox, oy, oz, dx, dy, dz, C):  # pragma: no cover - compiled
    """Whether the ray's line passes within C[6] of the segment C[0:3]-C[3:6]: the
    squared distance from a point of the segment to the line is convex in its position,
    so the clamped unconstrained minimiser is the nearest point."""
    ex, ey, ez = C[3] - C[0], C[4] - C[1], C[5] - C[2]
    wx, wy, wz = ox - C[0], oy - C[1], oz - C[2]
    dd = dx * dx + dy * dy + dz * dz
    ee = ex * ex + ey * ey + ez * ez
    de = dx * ex + dy * ey + dz * ez
    dw = dx * wx + dy * wy + dz * wz
    ew = ex * wx + ey * wy + ez * wz
    den = dd * ee - de * de
    s = 0.0
    if den > 1e-12 * dd * max(ee, 1e-12):
        s = min(max((dd * ew - de * dw) / den, 0.0), 1.0)
    qx, qy, qz = C[0] + s * ex - ox, C[1] + s * ey - oy, C[2] + s * ez - oz
    t = (qx * dx + qy * dy + qz * dz) / dd
    rx, ry, rz = qx - t * dx, qy - t * dy, qz - t * dz
    return rx * rx + ry * ry + rz * rz <= C[6] * C[6]


@njit(cache=True, fastmath=_FAST, error_model="numpy")
def _gather(ox, oy, oz, dx, dy, dz, spheres, cores, pool, n_pool, cand,
            t_near):  # pragma: no cover - compiled
    """Candidates of ``pool[:n_pool]`` whose bounding sphere and core capsule the ray
    meets beyond ``t_near``, in primitive order, and the span [t0, t1] of their
    spheres."""
    n_cand = 0
    t0, t1 = np.inf, -np.inf
    for j in range(n_pool):
        k = pool[j]
        lo, hi = _sphere_span(ox, oy, oz, dx, dy, dz, spheres[k])
        if hi < lo or hi <= t_near or not _near_core(ox, oy, oz, dx, dy, dz, cores[k]):
            continue
        cand[n_cand] = k
        n_cand += 1
        t0 = min(t0, lo)
        t1 = max(t1, hi)
    return n_cand, max(t0, t_near), t1


@njit(cache=True, fastmath=_FAST, error_model="numpy")
def _march(ox, oy, oz, dx, dy, dz, t0, t1, kinds, params, blend, cand,
           n_cand):  # pragma: no cover - compiled
    """First t in [t0, t1] where the field drops below the hit threshold, or inf.

    Over-relaxed sphere tracing (Keinert et al. 2014): steps are ``_RELAX`` times the
    field; when the spheres of two successive points do not overlap the step may have
    passed the surface, so it is taken back to the plain step and relaxation stops."""
    norm = math.sqrt(dx * dx + dy * dy + dz * dz)
    t = t0
    omega = _RELAX
    step = 0.0
    previous = 0.0
    for _ in range(_MAX_STEPS):
        if t > t1:
            return np.inf
        f = _field(ox + t * dx, oy + t * dy, oz + t * dz, kinds, params, blend, cand,
                   n_cand) / norm
        if omega > 1.0 and abs(f) + abs(previous) < step:
            step -= omega * step  # back to the end of the plain step
            omega = 1.0
        else:
            if f < _EPS / norm:
                return t
            step = omega * f
            previous = f
        t += step
    return np.inf


@njit(cache=True, fastmath=_FAST, error_model="numpy")
def first_hits(origins, directions, t_near, kinds, params, blend, spheres,
               cores):  # pragma: no cover - compiled
    """(M,) ray parameter of the first surface along rays o + t d, t > t_near, or inf."""
    n = kinds.shape[0]
    pool = np.arange(n)
    cand = np.empty(n, dtype=np.int64)
    out = np.full(origins.shape[0], np.inf)
    for m in range(origins.shape[0]):
        ox, oy, oz = origins[m, 0], origins[m, 1], origins[m, 2]
        dx, dy, dz = directions[m, 0], directions[m, 1], directions[m, 2]
        n_cand, t0, t1 = _gather(ox, oy, oz, dx, dy, dz, spheres, cores, pool, n, cand,
                                 t_near[m])
        if n_cand:
            out[m] = _march(ox, oy, oz, dx, dy, dz, t0, t1, kinds, params, blend, cand, n_cand)
    return out


@njit(cache=True, fastmath=_FAST, error_model="numpy", inline="always")
def _hash(ix, iy, iz, seed):  # pragma: no cover - compiled
    """A value in [0, 1) from integer lattice coordinates and a seed."""
    h = (ix * 374761393 + iy * 668265263 + iz * 2147483647 + seed * 144665) & 0xFFFFFFFF
    h = ((h ^ (h >> 13)) * 1274126177) & 0xFFFFFFFF
    h = h ^ (h >> 16)
    return (h & 0xFFFFFF) / 16777216.0


@njit(cache=True, fastmath=_FAST, error_model="numpy")
def value_noise(x, y, z, seed):  # pragma: no cover - compiled
    """Trilinear value noise in [0, 1) with smoothstep weights, lattice spacing 1."""
    fx, fy, fz = math.floor(x), math.floor(y), math.floor(z)
    ix, iy, iz = int(fx), int(fy), int(fz)
    tx, ty, tz = x - fx, y - fy, z - fz
    tx, ty, tz = tx * tx * (3 - 2 * tx), ty * ty * (3 - 2 * ty), tz * tz * (3 - 2 * tz)
    total = 0.0
    for c in range(8):
        cx, cy, cz = c & 1, (c >> 1) & 1, (c >> 2) & 1
        w = (tx if cx else 1 - tx) * (ty if cy else 1 - ty) * (tz if cz else 1 - tz)
        total += w * _hash(ix + cx, iy + cy, iz + cz, seed)
    return total


@njit(cache=True, fastmath=_FAST, error_model="numpy", parallel=True)
def flesh_kernel(kinds, params, blend, labels, far_labels, spheres, cores, blocks, frames,
                 nails, intrinsics, perspective, scale, light, material, albedo, nail_albedo, seed,
                 shadows, depth, label_image, rgb):  # pragma: no cover - compiled
    """Sphere trace every pixel into ``depth`` (H, W) float32 (start at inf),
    ``label_image`` (H, W) int16 and the shaded colour ``rgb`` (H, W, 3) float32.

    ``spheres`` (P, 4) bounding spheres, ``cores`` (P, 7) bounding capsules (segment,
    radius) inside them, ``blocks`` (P, 4) the capsules' pixel blocks (u0, u1, v0,
    v1; empty when u0 > u1); ``frames`` (P, 12) texture frame (origin, three axes) of each
    primitive; ``nails`` (P, 4) the dorsal unit vector of a distal phalanx and 1 (0 for no
    nail); ``light`` (3,) unit direction towards the light; ``material`` = (ambient,
    specular weight, shininess, nail specular weight, nail shininess, texture depth);
    ``albedo`` and ``nail_albedo`` (3,) RGB. Shading (Blinn-Phong):
    ``albedo * (ambient + (1 - ambient) s max(0, n.l)) + w_s s max(0, n.h)^shininess``,
    ``h`` the half vector of ``l`` and the direction to the eye, ``s`` the shadow factor
    (1, or 0 where the ray towards the light meets the hand when ``shadows``).
    """
    fx, s, cx, fy, cy = intrinsics[0], intrinsics[1], intrinsics[2], intrinsics[3], \
        intrinsics[4]
    height, width = depth.shape
    n = kinds.shape[0]
    ambient, spec_w, shine, nail_w, nail_shine, grain = material[0], material[1], \
        material[2], material[3], material[4], material[5]
    for v in prange(height):
        yn = (v - cy) / fy
        row = np.empty(n, dtype=np.int64)
        n_row = 0
        u_lo, u_hi = width, -1
        for k in range(n):
            if blocks[k, 0] <= blocks[k, 1] and blocks[k, 2] <= v <= blocks[k, 3]:
                row[n_row] = k
                n_row += 1
                u_lo = min(u_lo, blocks[k, 0])
                u_hi = max(u_hi, blocks[k, 1])
        if n_row == 0:
            continue
        pool = np.empty(n, dtype=np.int64)
        cand = np.empty(n, dtype=np.int64)
        every = np.arange(n)
        for u in range(u_lo, u_hi + 1):
            n_pool = 0
            for j in range(n_row):
                k = row[j]
                if blocks[k, 0] <= u <= blocks[k, 1]:
                    pool[n_pool] = k
                    n_pool += 1
            if n_pool == 0:
                continue
            xn = (u - cx - s * yn) / fx
            if perspective:
                ox, oy, dx, dy, dz = 0.0, 0.0, xn, yn, 1.0
            else:
                ox, oy, dx, dy, dz = xn / scale, yn / scale, 0.0, 0.0, 1.0
            n_cand, t0, t1 = _gather(ox, oy, 0.0, dx, dy, dz, spheres, cores, pool, n_pool,
                                     cand, 1e-6)
            if n_cand == 0:
                continue
            t = _march(ox, oy, 0.0, dx, dy, dz, t0, t1, kinds, params, blend, cand, n_cand)
            if not t < np.inf:
                continue
            px, py, pz = ox + t * dx, oy + t * dy, t * dz
            # label: the nearest primitive; a round cone's cap beyond b takes far_labels
            best, arg = np.inf, -1
            n_near = 0
            widest = 0.0
            for j in range(n_cand):
                widest = max(widest, blend[cand[j]])
            for j in range(n_cand):
                k = cand[j]
                d = _distance(kinds[k], px, py, pz, params[k])
                if d < best:
                    best, arg = d, k
                # terms further than twice the widest blend are plain minima with larger
                # values around this point: the normal needs only the others
                if d < 2.0 * widest + 4.0 * _GRAD_H + _EPS:
                    cand[n_near] = k  # (in order: n_near <= j)
                    n_near += 1
            n_cand = n_near
            P = params[arg]
            along = 0.0
            if kinds[arg] == ROUND_CONE:
                bx, by, bz = P[3] - P[0], P[4] - P[1], P[5] - P[2]
                along = ((px - P[0]) * bx + (py - P[1]) * by + (pz - P[2]) * bz) / \
                    (bx * bx + by * by + bz * bz)
            label_image[v, u] = far_labels[arg] if along > 1.0 else labels[arg]
            depth[v, u] = t
            # normal: tetrahedral finite differences of the field
            h = _GRAD_H
            f1 = _field(px + h, py - h, pz - h, kinds, params, blend, cand, n_cand)
            f2 = _field(px - h, py - h, pz + h, kinds, params, blend, cand, n_cand)
            f3 = _field(px - h, py + h, pz - h, kinds, params, blend, cand, n_cand)
            f4 = _field(px + h, py + h, pz + h, kinds, params, blend, cand, n_cand)
            nx, ny, nz = f1 - f2 - f3 + f4, -f1 - f2 + f3 + f4, -f1 + f2 - f3 + f4
            nn = math.sqrt(nx * nx + ny * ny + nz * nz)
            if nn > 0.0:
                nx, ny, nz = nx / nn, ny / nn, nz / nn
            # texture: two octaves of value noise in the primitive's own frame
            F = frames[arg]
            rx, ry, rz = px - F[0], py - F[1], pz - F[2]
            lx = rx * F[3] + ry * F[4] + rz * F[5]
            ly = rx * F[6] + ry * F[7] + rz * F[8]
            lz = rx * F[9] + ry * F[10] + rz * F[11]
            fine = value_noise(lx / 0.9, ly / 0.9, lz / 0.9, seed)
            coarse = value_noise(lx / 7.0, ly / 7.0, lz / 7.0, seed + 17)
            tex = 1.0 + grain * (0.7 * (fine - 0.5) + 1.3 * (coarse - 0.5))
            ar, ag, ab = albedo[0] * tex, albedo[1] * tex, albedo[2] * tex
            w_s, shin = spec_w, shine
            N = nails[arg]
            if N[3] > 0.0 and along > 0.45 and nx * N[0] + ny * N[1] + nz * N[2] > 0.6:
                ar, ag, ab = nail_albedo[0], nail_albedo[1], nail_albedo[2]
                w_s, shin = nail_w, nail_shine
            lam = nx * light[0] + ny * light[1] + nz * light[2]
            vis = 1.0
            if shadows and lam > 0.0:
                sx, sy, sz = px + 0.3 * nx, py + 0.3 * ny, pz + 0.3 * nz
                m_c, s0, s1 = _gather(sx, sy, sz, light[0], light[1], light[2], spheres,
                                      cores, every, n, pool, 0.0)
                if m_c and _march(sx, sy, sz, light[0], light[1], light[2], s0, s1, kinds,
                                  params, blend, pool, m_c) < np.inf:
                    vis = 0.0
            diffuse = ambient + (1.0 - ambient) * vis * max(lam, 0.0)
            vn = math.sqrt(dx * dx + dy * dy + dz * dz)
            hx, hy, hz = light[0] - dx / vn, light[1] - dy / vn, light[2] - dz / vn
            hn = math.sqrt(hx * hx + hy * hy + hz * hz)
            spec = 0.0
            if hn > 0.0 and lam > 0.0:
                spec = w_s * vis * max((nx * hx + ny * hy + nz * hz) / hn, 0.0) ** shin
            rgb[v, u, 0] = ar * diffuse + spec
            rgb[v, u, 1] = ag * diffuse + spec
            rgb[v, u, 2] = ab * diffuse + spec
