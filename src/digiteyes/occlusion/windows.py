"""Window functions in the image (Rehg thesis Sec. 3.3.1, eq. 3.4-3.6).

Each template has a window that is one inside the part's outline in the image and zero
outside; it masks out the templates behind it. We place the windows from the model:

* a link or a tip: a *capsule*, the set of pixels within ``r`` px of the segment between
  the projected axis ends (one point for a tip), ``r`` the part's radius projected at the
  depth of its centre;
* the palm: the convex *polygon* of the projected corners of its template face.

With ``d(w)`` the signed distance of pixel ``w`` inside the outline (px, positive
inside), the unit window of thesis Sec. 4.4.2 is ``M = [d >= 0]`` and the smooth window is
``M = 1 / (1 + exp(-d / tau))`` with a width ``tau`` in pixels; the smooth one has a
gradient at the boundary, which is what the boundary Jacobian (eq. 3.12) needs. The
window geometry comes with its derivatives with respect to the tangent step of the
state, so the compiled layered error can differentiate ``M`` along both the pixel and
the window motion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from digiteyes.camera import Camera
from digiteyes.kinematics import Kinematics, point_jacobian
from digiteyes.occlusion.parts import TemplatePart, TemplatePlane

CAPSULE, POLYGON = 0, 1


@dataclass
class ImageWindows:
    """Window outlines of all parts in one camera, with Jacobians.

    Attributes
    ----------
    kind : (K,) int, :data:`CAPSULE` or :data:`POLYGON`.
    points : (K, 4, 2) px: a capsule's segment ends in rows 0 and 1 (equal for a tip),
        a polygon's four corners in order.
    radius : (K,) capsule radius, px (polygons: 0).
    d_points : (K, 4, 2, n_v) derivatives of ``points`` by the tangent step.
    d_radius : (K, n_v) derivative of ``radius``.
    depth : (K, 4) camera depth of the points, mm (for the occlusion relations).
    world : (K, 4, 3) the world points behind ``points``, mm.
    """

    kind: np.ndarray
    points: np.ndarray
    radius: np.ndarray
    d_points: np.ndarray
    d_radius: np.ndarray
    depth: np.ndarray
    world: np.ndarray

    def bounds(self) -> np.ndarray:
        """(K, 4) pixel boxes ``[u_min, v_min, u_max, v_max]`` of the windows."""
        low = self.points.min(axis=1) - self.radius[:, None]
        high = self.points.max(axis=1) + self.radius[:, None]
        return np.concatenate([low, high], axis=1)


def window_shape_points(part: TemplatePart, plane: TemplatePlane) -> np.ndarray:
    """The four shape-frame points (4, 3) that outline ``part``'s window, mm."""
    if part.kind == "link":
        end = np.array([part.length, 0.0, 0.0])
        return np.array([np.zeros(3), end, end, np.zeros(3)])
    if part.kind == "tip":
        return np.zeros((4, 3))
    ha, hb = 0.5 * part.size[0] * plane.e_a, 0.5 * part.size[1] * plane.e_b
    o = plane.origin
    return np.array([o - ha - hb, o + ha - hb, o + ha + hb, o - ha + hb])


def image_windows(parts: tuple[TemplatePart, ...], planes: list[TemplatePlane],
                  kin: Kinematics, camera: Camera) -> ImageWindows:
    """The windows of ``parts`` (planes as used by their templates) in ``camera`` at the
    state of ``kin`` (one state), with their Jacobians."""
    K = len(parts)
    rows = np.repeat([p.row for p in parts], 4)
    p_shape = np.concatenate([window_shape_points(p, pl) for p, pl in
                              zip(parts, planes, strict=True)])
    p_world, J_world = point_jacobian(kin, rows, p_shape)
    w, J_pix = camera.project_with_jacobian(p_world)
    d_points = J_pix @ J_world
    depth = camera.depth(p_world)
    kind = np.array([POLYGON if p.kind == "palm" else CAPSULE for p in parts])
    capsule = kind == CAPSULE
    radii = np.array([p.radius if c else 0.0 for p, c in zip(parts, capsule, strict=True)])
    f = float(camera.K[0, 0])
    n_v = J_world.shape[-1]
    if camera.projection == "perspective":
        # a capsule's image radius f r / z at the depth z of its axis's midpoint
        z = np.where(capsule, 0.5 * (depth[0::4] + depth[1::4]), 1.0)
        dz = 0.5 * (camera.T_cam_world[2, :3] @ (J_world[0::4] + J_world[1::4]))
        radius = radii * f / z
        d_radius = (-radii * f / (z * z))[:, None] * dz
    else:
        scale = 1.0 if camera.projection == "orthographic" else 1.0 / camera.depth_mm
        radius = radii * f * scale
        d_radius = np.zeros((K, n_v))
    return ImageWindows(kind, np.ascontiguousarray(w.reshape(K, 4, 2)), radius,
                        np.ascontiguousarray(d_points.reshape(K, 4, 2, n_v)), d_radius,
                        depth.reshape(K, 4), p_world.reshape(K, 4, 3))
