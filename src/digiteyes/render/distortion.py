"""Lens distortion for rendered images: render ideal (pinhole) images, then warp them.

Rays are cast without distortion. For a camera with OpenCV distortion coefficients, every
output pixel w_d looks up the ideal image at ``K undistort(K^-1 w_d)``, so that the
warped image agrees with :meth:`digiteyes.camera.Camera.project` (which distorts
normalised coordinates, then applies K with its skew). The ideal image is rendered on a
canvas large enough to hold every looked-up position (barrel distortion looks outside
the image). The look-up maps are cached per camera.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from digiteyes.camera import Camera
from digiteyes.render.pixels import PixelGrid

_MAX_CANVAS_FACTOR = 3  # the canvas never exceeds this many image sizes per axis


@dataclass(frozen=True)
class DistortionWarp:
    """Look-up maps (H, W) float32 into a canvas whose pixel (0, 0) is the ideal image's
    pixel (u_min, v_min); the canvas is ``canvas_width`` x ``canvas_height`` pixels."""

    map_u: np.ndarray
    map_v: np.ndarray
    u_min: int
    v_min: int
    canvas_width: int
    canvas_height: int

    def warp(self, image: np.ndarray, nearest: bool, fill: float) -> np.ndarray:
        """Warp a canvas image to the distorted camera image; outside the canvas: fill."""
        mode = cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR
        return cv2.remap(image, self.map_u, self.map_v, mode,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=fill)


def camera_canvas(cam: Camera) -> tuple[PixelGrid, DistortionWarp | None]:
    """The grid to ray cast for ``cam`` and the warp that turns it into the camera's image:
    the camera's own grid and None without distortion, else the warp's canvas."""
    grid = PixelGrid.from_camera(cam)
    warp = distortion_warp(cam)
    if warp is not None:
        grid = grid.canvas(warp.u_min, warp.v_min, warp.canvas_width, warp.canvas_height)
    return grid, warp


def distortion_warp(cam: Camera) -> DistortionWarp | None:
    """The warp of a camera with distortion, None for a distortion-free camera."""
    if cam.projection != "perspective" or not np.any(cam.dist):
        return None
    return _warp(cam.K.tobytes(), cam.dist.tobytes(), cam.width, cam.height)


@lru_cache(maxsize=16)
def _warp(K_bytes: bytes, dist_bytes: bytes, width: int, height: int) -> DistortionWarp:
    K = np.frombuffer(K_bytes).reshape(3, 3)
    dist = np.frombuffer(dist_bytes)
    u, v = np.meshgrid(np.arange(width, dtype=float), np.arange(height, dtype=float))
    pixels = np.stack([u.ravel(), v.ravel(), np.ones(u.size)], axis=1)
    distorted = (pixels @ np.linalg.inv(K).T)[:, :2]
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
    ideal = cv2.undistortPoints(distorted.reshape(-1, 1, 2), np.eye(3), dist,
                                criteria=criteria).reshape(-1, 2)
    ideal_px = ideal @ K[:2, :2].T + K[:2, 2]
    limit = np.array([_MAX_CANVAS_FACTOR * width, _MAX_CANVAS_FACTOR * height], dtype=float)
    low = np.clip(np.floor(ideal_px.min(axis=0)) - 1, -limit, 0).astype(int)
    high = np.clip(np.ceil(ideal_px.max(axis=0)) + 1, [width - 1, height - 1],
                   limit + np.array([width - 1, height - 1])).astype(int)
    map_u = (ideal_px[:, 0] - low[0]).reshape(height, width).astype(np.float32)
    map_v = (ideal_px[:, 1] - low[1]).reshape(height, width).astype(np.float32)
    return DistortionWarp(map_u, map_v, int(low[0]), int(low[1]),
                          int(high[0] - low[0] + 1), int(high[1] - low[1] + 1))
