"""Slice geometry and sampling for the DigitEyes link and tip trackers (report Sec. 4).

A *slice* is a short line segment in the image along which the intensity profile is read.
Link trackers use slices perpendicular to the projected link axis (report Fig. 5, thesis
Fig. 4.2); tip trackers use slices along the axis, beyond the distal link. This module

* converts an image once to a grey uint8 or float32 array (:func:`prepare_image`);
* predicts where the silhouette of a cylinder or a sphere lies around its projected axis
  or centre (:func:`cylinder_tangent_points`, :func:`sphere_tangent_points`), from the
  exact tangent points of the viewing rays, which the caller projects with
  ``camera.project`` (so perspective, orthographic and scaled orthographic cameras are
  handled alike);
* samples slices bilinearly (:func:`bilinear`, :func:`sample_profiles`).

The compiled pieces (:func:`tangent_pair`, :func:`bilinear`) are also called by the fused
measurement loop of ``features/_kernels.py``.

Pixel (0, 0) is the centre of the top-left pixel (DESIGN.md Sec. 3); world points in mm.
"""

from __future__ import annotations

import cv2
import numpy as np
from numba import njit

from digiteyes.camera import Camera
from digiteyes.errors import CameraError


def prepare_image(image: np.ndarray) -> np.ndarray:
    """Grey (H, W) array of an image (H, W), (H, W, 1), (H, W, 3) RGB or (H, W, 4) RGBA,
    as the compiled samplers read it: uint8 or float32, C-contiguous.

    Grey levels keep the input scale (0..255 for uint8). A C-contiguous uint8 or float32
    grey image is returned as is (no copy: converting a 640x480 frame to float32 cost
    more than 0.1 ms, docs/features.md "Performance"); other grey types become float32;
    colour is converted to grey.
    """
    image = np.asarray(image)
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[..., 0]
    if image.ndim == 2:
        if image.dtype in (np.uint8, np.float32) and image.flags.c_contiguous:
            return image
        if image.dtype == np.uint8:
            return np.ascontiguousarray(image)
        return np.ascontiguousarray(image, dtype=np.float32)
    if image.ndim == 3 and image.shape[2] in (3, 4):
        code = cv2.COLOR_RGB2GRAY if image.shape[2] == 3 else cv2.COLOR_RGBA2GRAY
        source = image if image.dtype in (np.uint8, np.float32) else image.astype(np.float32)
        grey = cv2.cvtColor(np.ascontiguousarray(source), code)
        return grey if grey.dtype == np.uint8 else np.ascontiguousarray(grey, dtype=np.float32)
    raise CameraError(
        f"images must be (H, W) grey or (H, W, 3) RGB arrays, got shape {image.shape}"
    )


def perpendicular(u: np.ndarray) -> np.ndarray:
    """Image vectors (..., 2) turned by +90 degrees in pixel axes: ``(-u_y, u_x)``."""
    return np.stack([-u[..., 1], u[..., 0]], axis=-1)


def view_of(camera: Camera) -> tuple[np.ndarray, bool]:
    """Optical centre (perspective) or optical axis direction (parallel), world frame."""
    if camera.projection == "perspective":
        return camera.centre_world, True
    return np.ascontiguousarray(camera.T_cam_world[2, :3]), False


@njit(cache=True, error_model="numpy")
def tangent_pair(cx, cy, cz, ex, ey, ez, r, view, perspective, sphere,
                 out):  # pragma: no cover - compiled
    """Tangent points (2, 3) into ``out`` of a cylinder cross-section (``sphere`` False:
    the two contours) or a sphere (True: along ``e`` and beside it) centred at ``c``, with
    axis or direction ``e``; ``view`` is the optical centre (perspective) or the viewing
    direction. Returns the sine of the angle between ``e`` and the viewing ray."""
    vx, vy, vz = view[0], view[1], view[2]
    if perspective:
        vx, vy, vz = cx - vx, cy - vy, cz - vz
    distance = np.sqrt(vx * vx + vy * vy + vz * vz)
    vx, vy, vz = vx / distance, vy / distance, vz / distance
    if sphere:  # tangent points towards e (out[0]) and beside it (out[1])
        k = ex * vx + ey * vy + ez * vz
        sx, sy, sz = ex - k * vx, ey - k * vy, ez - k * vz
    else:  # the part of the viewing direction across the axis
        k = vx * ex + vy * ey + vz * ez
        sx, sy, sz = vx - k * ex, vy - k * ey, vz - k * ez
    s = np.sqrt(sx * sx + sy * sy + sz * sz)
    sx, sy, sz = sx / s, sy / s, sz / s
    if sphere:  # other = v x side
        ox, oy, oz = vy * sz - vz * sy, vz * sx - vx * sz, vx * sy - vy * sx
        ratio = r / distance if perspective else 0.0
        along = r * np.sqrt(1.0 - ratio * ratio)
        bx, by, bz = cx - r * ratio * vx, cy - r * ratio * vy, cz - r * ratio * vz
        out[0, 0], out[0, 1], out[0, 2] = bx + along * sx, by + along * sy, bz + along * sz
        out[1, 0], out[1, 1], out[1, 2] = bx + along * ox, by + along * oy, bz + along * oz
    else:  # w = e x side
        wx, wy, wz = ey * sz - ez * sy, ez * sx - ex * sz, ex * sy - ey * sx
        ratio = r / (distance * s) if perspective else 0.0
        along = r * np.sqrt(1.0 - ratio * ratio)
        bx, by, bz = cx - r * ratio * sx, cy - r * ratio * sy, cz - r * ratio * sz
        out[0, 0], out[0, 1], out[0, 2] = bx - along * wx, by - along * wy, bz - along * wz
        out[1, 0], out[1, 1], out[1, 2] = bx + along * wx, by + along * wy, bz + along * wz
    return s


@njit(cache=True)
def _tangent_kernel(centres, directions, radius, view, perspective, sphere, out,
                    sin_view):  # pragma: no cover - compiled
    for i in range(centres.shape[0]):
        sin_view[i] = tangent_pair(centres[i, 0], centres[i, 1], centres[i, 2],
                                   directions[i, 0], directions[i, 1], directions[i, 2],
                                   radius[i], view, perspective, sphere, out[i])


def _tangent_points(camera, centres, directions, radius, sphere):
    centres, directions, radius = np.broadcast_arrays(
        np.asarray(centres, dtype=float), np.asarray(directions, dtype=float),
        np.asarray(radius, dtype=float)[..., None])
    lead = centres.shape[:-1]
    view, perspective = view_of(camera)
    out = np.empty((*lead, 2, 3))
    sin_view = np.empty(lead)
    _tangent_kernel(np.array(centres.reshape(-1, 3)), np.array(directions.reshape(-1, 3)),
                    np.array(radius[..., 0].reshape(-1)), view, perspective, sphere,
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


@njit(cache=True, inline="always")
def bilinear(gray, x, y):  # pragma: no cover - compiled
    """Bilinear grey level at pixel ``(x, y)`` of a uint8 or float image; NaN unless
    ``0 <= x < W - 1`` and ``0 <= y < H - 1`` (the whole neighbourhood inside the image)."""
    # Plain float comparisons (NaN fails them): the chained int/float form compiled to
    # code 2.5 times slower for the whole sample (docs/features.md, "Performance").
    if x >= 0.0 and y >= 0.0 and x < float(gray.shape[1] - 1) and y < float(gray.shape[0] - 1):
        x0, y0 = int(x), int(y)
        fx, fy = x - x0, y - y0
        # float() first: differences of uint8 pixels would wrap around
        a, b = float(gray[y0, x0]), float(gray[y0, x0 + 1])
        c, d = float(gray[y0 + 1, x0]), float(gray[y0 + 1, x0 + 1])
        top = a + fx * (b - a)
        return top + fy * (c + fx * (d - c) - top)
    return np.nan


@njit(cache=True)
def _sample_kernel(gray, origins, directions, offsets, profiles):  # pragma: no cover
    for i in range(origins.shape[0]):
        for j in range(offsets.shape[0]):
            profiles[i, j] = bilinear(gray, origins[i, 0] + offsets[j] * directions[i, 0],
                                      origins[i, 1] + offsets[j] * directions[i, 1])


def sample_profiles(
    gray: np.ndarray,
    origins: np.ndarray,
    directions: np.ndarray,
    offsets: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Bilinear intensity profiles along many slices (one compiled loop, :func:`bilinear`).

    Sample ``j`` of a slice is at ``origin + offsets[j] * direction``. Samples whose
    bilinear neighbourhood leaves the image are NaN (so no edge is ever found at the image
    border).

    Parameters
    ----------
    gray : (H, W) grey image (:func:`prepare_image` gives one).
    origins : (..., 2) slice origins, px.
    directions : (..., 2) unit slice directions (broadcast against ``origins``).
    offsets : (J,) sample positions along each slice, px.

    Returns
    -------
    profiles : (..., J) grey levels, NaN outside the image.
    inside : (..., J) bool, the sample is inside (``0 <= x < W - 1``, same in y).
    """
    origins, directions = np.broadcast_arrays(np.asarray(origins, dtype=float),
                                              np.asarray(directions, dtype=float))
    lead, n = origins.shape[:-1], len(offsets)
    profiles = np.empty((int(np.prod(lead)), n))
    _sample_kernel(prepare_image(gray),
                   np.ascontiguousarray(origins.reshape(-1, 2)),
                   np.ascontiguousarray(directions.reshape(-1, 2)),
                   np.asarray(offsets, dtype=float), profiles)
    profiles = profiles.reshape(*lead, n)
    return profiles, ~np.isnan(profiles)
