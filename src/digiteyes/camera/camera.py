"""Camera models: perspective pinhole with OpenCV distortion, orthographic, scaled
orthographic (thesis eq. 2.5-2.8; Huang, Wu & Lin Sec. 4.2), with Jacobians.

Conventions (DESIGN.md Sec. 3): the camera frame is OpenCV's (x right, y down, z forward);
``T_cam_world`` maps world mm to camera mm; pixel (0, 0) is the centre of the top-left
pixel; ``K`` is OpenCV's 3x3 intrinsic matrix and ``dist`` OpenCV's (k1, k2, p1, p2, k3).

* perspective (eq. 2.6): ``w = K [distort(x/z, y/z), 1]``;
* orthographic (eq. 2.7-2.8): ``w = (fx x + s y + cx, fy y + cy)``, ``fx``/``fy`` in pixels
  per mm;
* scaled orthographic (weak perspective): ``w = (fx x / Z0 + s y / Z0 + cx, fy y / Z0 + cy)``
  with a fixed reference depth ``Z0 = depth_mm``.

Projection and its Jacobian run in one compiled loop (numba, :func:`project_point`): the
trackers project a few hundred points per camera and iteration, where numpy's per-call
overhead cost more than the arithmetic.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import numpy as np
from numba import njit

from digiteyes.errors import CameraError

Projection = Literal["perspective", "orthographic", "scaled-orthographic"]
PROJECTIONS = ("perspective", "orthographic", "scaled-orthographic")



@njit(cache=True, inline="always")
def project_point(params, px, py, pz):  # pragma: no cover - compiled
    """Pixel ``(u, v)`` and camera-frame coordinates of one world point, for compiled
    callers (:attr:`Camera.projection_params` layout): returns ``u, v, x, y, z``."""
    x = params[0] * px + params[1] * py + params[2] * pz + params[9]
    y = params[3] * px + params[4] * py + params[5] * pz + params[10]
    z = params[6] * px + params[7] * py + params[8] * pz + params[11]
    fx, s, cx, fy, cy = params[12], params[13], params[14], params[15], params[16]
    if params[22] == 0.0:  # perspective with distortion (thesis eq. 2.6)
        xn, yn = x / z, y / z
        k1, k2, p1, p2, k3 = params[17], params[18], params[19], params[20], params[21]
        r2 = xn * xn + yn * yn
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = xn * radial + 2.0 * p1 * xn * yn + p2 * (r2 + 2.0 * xn * xn)
        yd = yn * radial + p1 * (r2 + 2.0 * yn * yn) + 2.0 * p2 * xn * yn
        return fx * xd + s * yd + cx, fy * yd + cy, x, y, z
    scale = 1.0 if params[22] == 1.0 else 1.0 / params[23]  # eq. 2.7-2.8, weak perspective
    return scale * (fx * x + s * y) + cx, scale * fy * y + cy, x, y, z


@njit(cache=True)
def project_kernel(params, points, w, J, jacobian):  # pragma: no cover - compiled
    """Pixels ``w`` (P, 2) and, if ``jacobian``, ``dw/dp_world`` ``J`` (P, 2, 3)."""
    fx, s, fy = params[12], params[13], params[15]
    for i in range(points.shape[0]):
        u, v, x, y, z = project_point(params, points[i, 0], points[i, 1], points[i, 2])
        w[i, 0] = u
        w[i, 1] = v
        if not jacobian:
            continue
        if params[22] == 0.0:
            inv_z = 1.0 / z
            xn, yn = x * inv_z, y * inv_z
            k1, k2, p1, p2, k3 = params[17], params[18], params[19], params[20], params[21]
            r2 = xn * xn + yn * yn
            radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
            dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)  # d radial / d r2
            dxd_dxn = radial + 2.0 * xn * xn * dradial + 2.0 * p1 * yn + 6.0 * p2 * xn
            dxd_dyn = 2.0 * xn * yn * dradial + 2.0 * p1 * xn + 2.0 * p2 * yn
            dyd_dxn = dxd_dyn
            dyd_dyn = radial + 2.0 * yn * yn * dradial + 6.0 * p1 * yn + 2.0 * p2 * xn
            a00 = fx * dxd_dxn + s * dyd_dxn  # d w / d (xn, yn)
            a01 = fx * dxd_dyn + s * dyd_dyn
            a10 = fy * dyd_dxn
            a11 = fy * dyd_dyn
            # d (xn, yn) / d p_cam = [[1/z, 0, -xn/z], [0, 1/z, -yn/z]]
            c00, c01, c02 = a00 * inv_z, a01 * inv_z, -(a00 * xn + a01 * yn) * inv_z
            c10, c11, c12 = a10 * inv_z, a11 * inv_z, -(a10 * xn + a11 * yn) * inv_z
        else:
            scale = 1.0 if params[22] == 1.0 else 1.0 / params[23]
            c00, c01, c02 = scale * fx, scale * s, 0.0
            c10, c11, c12 = 0.0, scale * fy, 0.0
        for k in range(3):  # chain with R_cam_world
            J[i, 0, k] = c00 * params[k] + c01 * params[3 + k] + c02 * params[6 + k]
            J[i, 1, k] = c10 * params[k] + c11 * params[3 + k] + c12 * params[6 + k]



PROJECTION_PARAMS = 24
"""Length of :attr:`Camera.projection_params`."""
MAX_IMAGE_SIDE = 65_536
"""Largest image width or height a camera may have (pixels)."""


def _float_array(value: object, what: str, name: str) -> np.ndarray:
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise CameraError(f"camera {name!r}: {what} must be an array of numbers") from None


def _side(value: object, what: str, name: str) -> int:
    """An image side in pixels: an integer from 1 to :data:`MAX_IMAGE_SIDE`."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not np.isfinite(value) or not float(value).is_integer() \
            or not 1 <= value <= MAX_IMAGE_SIDE:
        raise CameraError(f"camera {name!r}: {what} must be an integer from 1 to "
                          f"{MAX_IMAGE_SIDE} pixels, got {value!r}")
    return int(value)


def _positive(value: object, what: str, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not np.isfinite(value) or not value > 0:
        raise CameraError(f"camera {name!r}: {what} must be a finite positive number, "
                          f"got {value!r}")
    return float(value)

@dataclass(frozen=True, eq=False)
class Camera:
    """One calibrated camera. Build with :meth:`create` (validates) or :meth:`look_at`.

    Attributes
    ----------
    name : label used in files and plots.
    K : (3, 3) intrinsics in pixels (orthographic: pixels per mm).
    width, height : image size in pixels.
    T_cam_world : (4, 4) rigid transform from world to camera coordinates, mm.
    dist : (5,) OpenCV distortion (k1, k2, p1, p2, k3); perspective cameras only.
    projection : ``"perspective"``, ``"orthographic"`` or ``"scaled-orthographic"``.
    depth_mm : reference depth Z0 of the scaled-orthographic model, mm.
    """

    name: str
    K: np.ndarray
    width: int
    height: int
    T_cam_world: np.ndarray
    dist: np.ndarray = field(default_factory=lambda: np.zeros(5))
    projection: Projection = "perspective"
    depth_mm: float = 1000.0

    @classmethod
    def create(
        cls,
        name: str,
        K: np.ndarray,
        width: int,
        height: int,
        T_cam_world: np.ndarray | None = None,
        dist: np.ndarray | None = None,
        projection: Projection = "perspective",
        depth_mm: float = 1000.0,
    ) -> Camera:
        """Validated constructor; raises :class:`CameraError` naming the bad parameter."""
        if not isinstance(name, str):
            raise CameraError(f"camera name must be a str, got {type(name).__name__}")
        K = _float_array(K, "K", name)
        width, height = _side(width, "width", name), _side(height, "height", name)
        depth_mm = _positive(depth_mm, "depth_mm", name)
        if T_cam_world is not None:
            T_cam_world = _float_array(T_cam_world, "T_cam_world", name)
        if dist is not None:
            dist = _float_array(dist, "dist", name)
        if K.shape != (3, 3) or not np.isfinite(K).all():
            raise CameraError(f"camera {name!r}: K must be a finite 3x3 matrix, got {K.shape}")
        if not (K[0, 0] > 0 and K[1, 1] > 0):
            raise CameraError(
                f"camera {name!r}: focal lengths must be positive, got fx={K[0, 0]:g}, "
                f"fy={K[1, 1]:g}"
            )
        if not np.allclose(K[2], [0.0, 0.0, 1.0]) or K[1, 0] != 0.0:
            raise CameraError(f"camera {name!r}: K must be upper triangular with K[2] = [0 0 1]")
        T = np.eye(4) if T_cam_world is None else np.array(T_cam_world, dtype=float)
        if T.shape != (4, 4) or not np.isfinite(T).all():
            raise CameraError(f"camera {name!r}: T_cam_world must be a finite 4x4 matrix")
        R = T[:3, :3]
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0 or \
                not np.allclose(T[3], [0, 0, 0, 1]):
            raise CameraError(f"camera {name!r}: T_cam_world must be a rigid transform")
        d = np.zeros(5)
        if dist is not None:
            given = np.ravel(np.asarray(dist, dtype=float))
            if given.size not in (0, 4, 5, 8, 12, 14) or not np.isfinite(given).all():
                raise CameraError(
                    f"camera {name!r}: dist must hold 4, 5, 8, 12 or 14 OpenCV coefficients "
                    f"(k1 k2 p1 p2 [k3 ...]), got {given.size}"
                )
            if np.any(given[5:]):
                raise CameraError(
                    f"camera {name!r}: only the k1 k2 p1 p2 k3 distortion model is supported; "
                    "the rational/prism/tilt coefficients must be zero"
                )
            d[:min(given.size, 5)] = given[:5]
        if projection not in PROJECTIONS:
            raise CameraError(
                f"camera {name!r}: projection must be one of {', '.join(PROJECTIONS)}, "
                f"got {projection!r}"
            )
        if projection != "perspective" and np.any(d):
            raise CameraError(f"camera {name!r}: distortion applies to perspective cameras only")
        for array in (K, T, d):
            array.setflags(write=False)
        return cls(name, K, int(width), int(height), T, d, projection, float(depth_mm))

    @classmethod
    def look_at(
        cls,
        name: str,
        eye: np.ndarray,
        target: np.ndarray,
        up: np.ndarray = (0.0, 0.0, 1.0),
        *,
        width: int = 640,
        height: int = 480,
        focal_px: float = 800.0,
        projection: Projection = "perspective",
    ) -> Camera:
        """A camera at ``eye`` (world mm) looking at ``target``, image ``up`` roughly along
        world ``up``, principal point at the image centre."""
        eye = np.asarray(eye, dtype=float)
        forward = np.asarray(target, dtype=float) - eye
        if np.linalg.norm(forward) == 0:
            raise CameraError(f"camera {name!r}: eye and target coincide")
        z = forward / np.linalg.norm(forward)
        x = np.cross(z, np.asarray(up, dtype=float))
        if np.linalg.norm(x) < 1e-9:
            raise CameraError(f"camera {name!r}: viewing direction is parallel to 'up'")
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        T_world_cam = np.eye(4)
        T_world_cam[:3, :3] = np.stack([x, y, z], axis=1)
        T_world_cam[:3, 3] = eye
        K = np.array([[focal_px, 0, (width - 1) / 2], [0, focal_px, (height - 1) / 2], [0, 0, 1]])
        depth = float(np.linalg.norm(forward))
        if projection == "orthographic":
            K[:2, :2] /= depth
        return cls.create(name, K, width, height, np.linalg.inv(T_world_cam),
                          projection=projection, depth_mm=depth)

    # ------------------------------------------------------------------ geometry
    @cached_property
    def projection_params(self) -> np.ndarray:
        """The camera as one read-only float array for compiled code (numba): rotation
        ``R_cam_world`` (9, row-major), translation (3), ``fx s cx fy cy`` (5), distortion
        (5), projection code (perspective 0, orthographic 1, scaled orthographic 2) and
        ``depth_mm``; see :func:`project_point`."""
        params = np.concatenate([
            np.asarray(self.T_cam_world, dtype=float)[:3, :3].ravel(),
            np.asarray(self.T_cam_world, dtype=float)[:3, 3],
            np.asarray(self.K, dtype=float)[[0, 0, 0, 1, 1], [0, 1, 2, 1, 2]],
            np.asarray(self.dist, dtype=float)[:5],
            [float(PROJECTIONS.index(self.projection)), float(self.depth_mm)],
        ])
        params.setflags(write=False)
        return params

    @property
    def T_world_cam(self) -> np.ndarray:
        """Camera pose in the world (inverse of ``T_cam_world``)."""
        return np.linalg.inv(self.T_cam_world)

    @cached_property
    def centre_world(self) -> np.ndarray:
        """Optical centre in world mm (for orthographic cameras: the frame origin);
        read-only, computed once (the feature trackers ask for it at every iteration)."""
        R, t = self.T_cam_world[:3, :3], self.T_cam_world[:3, 3]
        centre = -R.T @ t
        centre.setflags(write=False)
        return centre

    def to_camera(self, p_world: np.ndarray) -> np.ndarray:
        """World points (..., 3) in camera coordinates (..., 3), mm."""
        p = np.asarray(p_world, dtype=float)
        return p @ self.T_cam_world[:3, :3].T + self.T_cam_world[:3, 3]

    def project(self, p_world: np.ndarray) -> np.ndarray:
        """Pixel coordinates (..., 2) of world points (..., 3)."""
        return self.project_with_jacobian(p_world, jacobian=False)[0]

    def project_with_jacobian(
        self, p_world: np.ndarray, jacobian: bool = True
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Pixels (..., 2) and, if asked, ``d pixel / d p_world`` (..., 2, 3) in px/mm.

        The Jacobian chains the projection derivative in camera coordinates with the
        camera rotation: ``dw/dp_world = dw/dp_cam R_cam_world``.
        """
        p = np.asarray(p_world, dtype=float)
        lead = p.shape[:-1]
        flat = np.ascontiguousarray(p.reshape(-1, 3))
        w = np.empty((len(flat), 2))
        J = np.empty((len(flat), 2, 3)) if jacobian else np.empty((0, 2, 3))
        project_kernel(self.projection_params, flat, w, J, jacobian)
        return w.reshape(*lead, 2), J.reshape(*lead, 2, 3) if jacobian else None

    def depth(self, p_world: np.ndarray) -> np.ndarray:
        """Depth along the optical axis (camera z) of world points, mm."""
        return self.to_camera(p_world)[..., 2]

    def in_image(self, w: np.ndarray, margin: float = 0.0) -> np.ndarray:
        """Boolean mask: pixel positions (..., 2) inside the image by at least ``margin``."""
        w = np.asarray(w, dtype=float)
        return ((w[..., 0] >= -0.5 + margin) & (w[..., 0] <= self.width - 0.5 - margin)
                & (w[..., 1] >= -0.5 + margin) & (w[..., 1] <= self.height - 0.5 - margin))

    def viewing_rays(self, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World ray origins and unit directions (..., 3) through pixel centres (no
        distortion: the renderer draws ideal images and distorts them afterwards)."""
        pixels = np.asarray(pixels, dtype=float)
        R_world_cam = self.T_cam_world[:3, :3].T
        Kinv = np.linalg.inv(self.K)
        homog = np.concatenate([pixels, np.ones((*pixels.shape[:-1], 1))], axis=-1)
        if self.projection == "perspective":
            d_cam = homog @ Kinv.T
            d_cam /= np.linalg.norm(d_cam, axis=-1, keepdims=True)
            origins = np.broadcast_to(self.centre_world, d_cam.shape)
            return origins.copy(), d_cam @ R_world_cam.T
        scale = 1.0 if self.projection == "orthographic" else 1.0 / self.depth_mm
        xy = (homog @ Kinv.T)[..., :2] / scale
        p_cam = np.concatenate([xy, np.zeros((*xy.shape[:-1], 1))], axis=-1)
        origins = p_cam @ R_world_cam.T + self.centre_world
        direction = np.broadcast_to(R_world_cam[:, 2], origins.shape).copy()
        return origins, direction
