"""Slice geometry and sampling for the DigitEyes link and tip trackers (report Sec. 4).

A *slice* is a short line segment in the image along which the intensity profile is read.
Link trackers use slices perpendicular to the projected link axis (report Fig. 5, thesis
Fig. 4.2); tip trackers use slices along the axis, beyond the distal link. This module

* converts an image once to a grey float32 array (:func:`prepare_image`);
* predicts where the silhouette of a cylinder or a sphere lies around its projected axis
  or centre (:func:`cylinder_tangent_points`, :func:`sphere_tangent_points`), from the
  exact tangent points of the viewing rays, which the caller projects with
  ``camera.project`` (so perspective, orthographic and scaled orthographic cameras are
  handled alike);
* samples every slice of every link with one bilinear lookup (:func:`sample_profiles`,
  one compiled loop over all samples).

Pixel (0, 0) is the centre of the top-left pixel (DESIGN.md Sec. 3); world points in mm.
"""

from __future__ import annotations

import cv2
import numpy as np
from numba import njit

from digiteyes.camera import Camera
from digiteyes.errors import CameraError


def prepare_image(image: np.ndarray) -> np.ndarray:
    """Grey float32 copy of an image (H, W), (H, W, 1), (H, W, 3) RGB or (H, W, 4) RGBA.

    Grey levels keep the input scale (0..255 for uint8). A C-contiguous float32 (H, W)
    array is returned as is, so trackers can convert a frame once and measure it in every
    Gauss-Newton iteration without copies.
    """
    image = np.asarray(image)
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[..., 0]
    if image.ndim == 2:
        if image.dtype == np.float32 and image.flags.c_contiguous:
            return image
        return np.ascontiguousarray(image, dtype=np.float32)
    if image.ndim == 3 and image.shape[2] in (3, 4):
        code = cv2.COLOR_RGB2GRAY if image.shape[2] == 3 else cv2.COLOR_RGBA2GRAY
        source = image if image.dtype in (np.uint8, np.float32) else image.astype(np.float32)
        return np.ascontiguousarray(cv2.cvtColor(np.ascontiguousarray(source), code),
                                    dtype=np.float32)
    raise CameraError(
        f"images must be (H, W) grey or (H, W, 3) RGB arrays, got shape {image.shape}"
    )


def perpendicular(u: np.ndarray) -> np.ndarray:
    """Image vectors (..., 2) turned by +90 degrees in pixel axes: ``(-u_y, u_x)``."""
    return np.stack([-u[..., 1], u[..., 0]], axis=-1)


def _view(camera: Camera) -> tuple[np.ndarray, bool]:
    """Optical centre (perspective) or optical axis direction (parallel), world frame."""
    if camera.projection == "perspective":
        return camera.centre_world, True
    return np.ascontiguousarray(camera.T_cam_world[2, :3]), False


@njit(cache=True, error_model="numpy")
def _tangent_kernel(centres, directions, radius, view, perspective, sphere, out,
                    sin_view):  # pragma: no cover - compiled
    for i in range(centres.shape[0]):
        c = centres[i]
        e = directions[i]
        r = radius[i]
        if perspective:
            v = c - view
        else:
            v = view.copy()
        distance = np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        v = v / distance
        if sphere:  # tangent points towards e (out[0]) and beside it (out[1])
            side = e - (e[0] * v[0] + e[1] * v[1] + e[2] * v[2]) * v
        else:  # the part of the viewing direction across the axis
            side = v - (v[0] * e[0] + v[1] * e[1] + v[2] * e[2]) * e
        s = np.sqrt(side[0] * side[0] + side[1] * side[1] + side[2] * side[2])
        sin_view[i] = s
        side = side / s
        if sphere:
            other = np.array([v[1] * side[2] - v[2] * side[1], v[2] * side[0] - v[0] * side[2],
                              v[0] * side[1] - v[1] * side[0]])
            ratio = r / distance if perspective else 0.0
            along = r * np.sqrt(1.0 - ratio * ratio)
            base = c - (r * ratio) * v
            out[i, 0] = base + along * side
            out[i, 1] = base + along * other
        else:
            w = np.array([e[1] * side[2] - e[2] * side[1], e[2] * side[0] - e[0] * side[2],
                          e[0] * side[1] - e[1] * side[0]])
            ratio = r / (distance * s) if perspective else 0.0
            along = r * np.sqrt(1.0 - ratio * ratio)
            base = c - (r * ratio) * side
            out[i, 0] = base - along * w
            out[i, 1] = base + along * w


def _tangent_points(camera, centres, directions, radius, sphere):
    centres, directions, radius = np.broadcast_arrays(
        np.asarray(centres, dtype=float), np.asarray(directions, dtype=float),
        np.asarray(radius, dtype=float)[..., None])
    lead = centres.shape[:-1]
    view, perspective = _view(camera)
    out = np.empty((*lead, 2, 3))
    sin_view = np.empty(lead)
    _tangent_kernel(np.ascontiguousarray(centres.reshape(-1, 3)),
                    np.ascontiguousarray(directions.reshape(-1, 3)),
                    np.ascontiguousarray(radius[..., 0].reshape(-1)), view, perspective, sphere,
                    out.reshape(-1, 2, 3), sin_view.reshape(-1))
    return out, sin_view


def cylinder_tangent_points(
    camera: Camera, p_world: np.ndarray, axis_world: np.ndarray, radius: np.ndarray
) -> np.ndarray:
    """Points where viewing rays graze a cylinder, on the cross-sections through ``p``.

    At an axis point ``p`` the rays touching the cylinder meet its surface at ``p + r N``
    with ``N = -(r/D) v +- sqrt(1 - (r/D)^2) w``: ``v`` is the unit component of the
    viewing direction perpendicular to the axis, ``D`` the distance of the optical centre
    from the axis (``inf`` for parallel projection, where ``N = +-w``) and
    ``w = axis x v``. Their projections lie on the two occluding contours.

    Parameters
    ----------
    p_world : (..., 3) points on the axis, mm.
    axis_world : (..., 3) unit axis directions (broadcast against ``p_world``).
    radius : (...,) cylinder radii, mm.

    Returns
    -------
    (..., 2, 3) world tangent points, mm (NaN where the optical centre lies inside the
    cylinder or the axis is along the viewing ray).
    """
    return _tangent_points(camera, p_world, axis_world, radius, False)[0]


def sphere_tangent_points(
    camera: Camera, centre_world: np.ndarray, direction_world: np.ndarray, radius: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Silhouette points of spheres along and across an image direction.

    The silhouette point of a sphere on the side of the 3D direction ``e`` is the tangent
    point ``c + r N`` with ``N = -(r/d) v + sqrt(1 - (r/d)^2) e_perp`` (``v`` the unit viewing
    direction, ``d`` the centre's distance, ``e_perp`` the unit part of ``e`` perpendicular
    to ``v``); the point beside it uses ``v x e_perp`` instead of ``e_perp``.

    Parameters
    ----------
    centre_world : (T, 3) sphere centres, mm.
    direction_world : (T, 3) unit 3D directions (the finger axis, pointing outward).
    radius : (T,) radii, mm.

    Returns
    -------
    points : (T, 2, 3) tangent points along and beside, mm.
    sin_view : (T,) sine of the angle between the direction and the viewing ray (small
        values mean the finger points at or away from the camera).
    """
    return _tangent_points(camera, centre_world, direction_world, radius, True)


@njit(cache=True)
def _sample_kernel(gray, origins, directions, offsets, profiles, inside):  # pragma: no cover
    height, width = gray.shape
    for r in range(origins.shape[0]):
        ox, oy = origins[r, 0], origins[r, 1]
        dx, dy = directions[r, 0], directions[r, 1]
        for j in range(offsets.shape[0]):
            x = ox + offsets[j] * dx
            y = oy + offsets[j] * dy
            inside[r, j] = -0.5 <= x <= width - 0.5 and -0.5 <= y <= height - 0.5
            if not (np.isfinite(x) and np.isfinite(y)):
                profiles[r, j] = 0.0
                continue
            x = min(max(x, 0.0), width - 1.0)
            y = min(max(y, 0.0), height - 1.0)
            x0 = min(int(x), width - 2) if width > 1 else 0
            y0 = min(int(y), height - 2) if height > 1 else 0
            x1 = min(x0 + 1, width - 1)
            y1 = min(y0 + 1, height - 1)
            fx = x - x0
            fy = y - y0
            top = gray[y0, x0] + fx * (gray[y0, x1] - gray[y0, x0])
            bottom = gray[y1, x0] + fx * (gray[y1, x1] - gray[y1, x0])
            profiles[r, j] = top + fy * (bottom - top)


def sample_profiles(
    gray: np.ndarray,
    origins: np.ndarray,
    directions: np.ndarray,
    offsets: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear intensity profiles along many slices, in one compiled lookup.

    Sample ``j`` of a slice is at ``origin + offsets[j] * direction``. Outside the image
    the border is replicated (so the image border is never taken for an edge). This is the
    lookup ``cv2.remap`` does (the tests compare the two); doing it in one numba loop avoids
    building the coordinate maps with a dozen numpy operations and reads the image in
    double precision (OpenCV snaps sample positions to 1/32 px).

    Parameters
    ----------
    gray : (H, W) float32 image from :func:`prepare_image`.
    origins : (..., 2) slice origins, px.
    directions : (..., 2) unit slice directions (broadcast against ``origins``).
    offsets : (J,) sample positions along each slice, px.

    Returns
    -------
    profiles : (..., J) float64 grey levels.
    inside : (..., J) bool, sample inside the image (``-0.5 <= x <= W - 0.5``, same in y).
    """
    origins, directions = np.broadcast_arrays(np.asarray(origins, dtype=np.float64),
                                              np.asarray(directions, dtype=np.float64))
    lead = origins.shape[:-1]
    offsets = np.ascontiguousarray(offsets, dtype=np.float64)
    profiles = np.empty((*lead, len(offsets)))
    inside = np.empty((*lead, len(offsets)), dtype=np.bool_)
    _sample_kernel(gray, np.ascontiguousarray(origins.reshape(-1, 2)),
                   np.ascontiguousarray(directions.reshape(-1, 2)), offsets,
                   profiles.reshape(-1, len(offsets)), inside.reshape(-1, len(offsets)))
    return profiles, inside
