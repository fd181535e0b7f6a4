"""Pixel grids: camera-frame viewing rays for blocks of pixels, and projected bounds.

A :class:`PixelGrid` is the distortion-free part of a camera (intrinsics, projection
model, image size), possibly supersampled or enlarged into a canvas. Its rays are built in
the camera frame so that every direction has ``dz = 1`` and every origin ``oz = 0``: the
ray parameter of a hit is then its camera depth z (mm). For a perspective camera the rays
start at the optical centre and pass through ``K^-1 [u, v, 1]``; for orthographic and
scaled-orthographic cameras they are parallel to the optical axis and start on the plane
z = 0 at the point that projects to (u, v). They agree with
:meth:`digiteyes.camera.Camera.viewing_rays` (tests/render/test_pixels.py checks this).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from digiteyes.camera import Camera

_NEAR_MM = 1e-3


@dataclass(frozen=True)
class PixelGrid:
    """Distortion-free pixel-to-ray map of an image of ``width`` x ``height`` pixels.

    ``K`` (3, 3) follows :class:`~digiteyes.camera.Camera` (pixels per mm for the
    orthographic model); ``scale`` is 1 for perspective and orthographic cameras and
    ``1 / depth_mm`` for scaled orthographic ones.
    """

    projection: str
    K: np.ndarray
    width: int
    height: int
    scale: float = 1.0

    @classmethod
    def from_camera(cls, cam: Camera) -> PixelGrid:
        """The grid of a camera's image, ignoring lens distortion."""
        scale = 1.0 / cam.depth_mm if cam.projection == "scaled-orthographic" else 1.0
        return cls(cam.projection, np.array(cam.K, dtype=float), cam.width, cam.height, scale)

    @property
    def perspective(self) -> bool:
        return self.projection == "perspective"

    def supersampled(self, factor: int) -> PixelGrid:
        """The grid with ``factor`` x ``factor`` samples per pixel: sample (i, j) of pixel
        (u, v) sits at ``u + (i + 0.5) / factor - 0.5``, so averaging each block of samples
        gives the pixel."""
        K = self.K.copy()
        K[:2] *= factor
        K[:2, 2] += 0.5 * (factor - 1)
        return PixelGrid(self.projection, K, self.width * factor, self.height * factor,
                         self.scale)

    def canvas(self, u_min: int, v_min: int, width: int, height: int) -> PixelGrid:
        """A grid whose pixel (0, 0) is this grid's pixel (u_min, v_min)."""
        K = self.K.copy()
        K[0, 2] -= u_min
        K[1, 2] -= v_min
        return PixelGrid(self.projection, K, width, height, self.scale)

    # ------------------------------------------------------------------ rays
    def _normalised(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Inverse intrinsics: (x, y) with ``u = fx x + s y + cx``, ``v = fy y + cy``."""
        (fx, s, cx), (_, fy, cy) = self.K[0], self.K[1]
        y = (v - cy) / fy
        return (u - cx - s * y) / fx, y

    def rays(self, u0: int, u1: int, v0: int, v1: int) -> tuple[tuple, tuple]:
        """Camera-frame rays through the pixel block u0..u1, v0..v1 (inclusive).

        Returns ``(o, d)``, triples of floats or arrays broadcasting to (v1-v0+1, u1-u0+1).
        """
        u = np.arange(u0, u1 + 1, dtype=float)[None, :]
        v = np.arange(v0, v1 + 1, dtype=float)[:, None]
        x, y = self._normalised(u, v)
        if self.perspective:
            return (0.0, 0.0, 0.0), (x, y, 1.0)
        return (x / self.scale, y / self.scale, 0.0), (0.0, 0.0, 1.0)

    def rays_through(self, p_cam: np.ndarray) -> tuple[tuple, tuple]:
        """Rays (M,)-shaped triples through camera-frame points p_cam (M, 3)."""
        p = np.asarray(p_cam, dtype=float)
        if self.perspective:
            z = p[:, 2]
            return (0.0, 0.0, 0.0), (p[:, 0] / z, p[:, 1] / z, 1.0)
        return (p[:, 0], p[:, 1], 0.0), (0.0, 0.0, 1.0)

    # ------------------------------------------------------------------ bounds
    def ball_bounds(self, centres: np.ndarray, radius: float) -> np.ndarray | None:
        """Pixel bounds (u_min, u_max, v_min, v_max) of the projections of balls
        (centres (M, 3), camera frame); None when a ball reaches behind the camera.

        Perspective: the extreme values of x/z over a ball are the tangents
        ``(c_x c_z +- r sqrt(c_x^2 + c_z^2 - r^2)) / (c_z^2 - r^2)`` (likewise for y), so
        the bounds are exact before the skew term, which is bounded by interval
        arithmetic.
        """
        c = np.asarray(centres, dtype=float)
        r = float(radius)
        if self.perspective:
            cz = c[:, 2]
            if (cz - r <= _NEAR_MM).any():
                return None
            denom = cz * cz - r * r
            spread_x = r * np.sqrt(c[:, 0] ** 2 + denom)
            spread_y = r * np.sqrt(c[:, 1] ** 2 + denom)
            x_lo, x_hi = (c[:, 0] * cz - spread_x) / denom, (c[:, 0] * cz + spread_x) / denom
            y_lo, y_hi = (c[:, 1] * cz - spread_y) / denom, (c[:, 1] * cz + spread_y) / denom
        else:
            x_lo, x_hi = (c[:, 0] - r) * self.scale, (c[:, 0] + r) * self.scale
            y_lo, y_hi = (c[:, 1] - r) * self.scale, (c[:, 1] + r) * self.scale
        return self._pixel_bounds(x_lo.min(), x_hi.max(), y_lo.min(), y_hi.max())

    def point_bounds(self, points: np.ndarray) -> np.ndarray | None:
        """Pixel bounds of the projections of camera-frame points (M, 3); None when a point
        lies behind a perspective camera. The bounds of a convex body's projection are
        those of its vertices."""
        p = np.asarray(points, dtype=float)
        if self.perspective:
            if (p[:, 2] <= _NEAR_MM).any():
                return None
            x, y = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
        else:
            x, y = p[:, 0] * self.scale, p[:, 1] * self.scale
        return self._pixel_bounds(x.min(), x.max(), y.min(), y.max())

    def _pixel_bounds(self, x_lo: float, x_hi: float, y_lo: float, y_hi: float) -> np.ndarray:
        (fx, s, cx), (_, fy, cy) = self.K[0], self.K[1]
        skew = (s * y_lo, s * y_hi)
        return np.array([fx * x_lo + min(skew) + cx, fx * x_hi + max(skew) + cx,
                         fy * y_lo + cy, fy * y_hi + cy])

    def pixel_block(self, bounds: np.ndarray | None) -> tuple[int, int, int, int] | None:
        """Inclusive pixel block (u0, u1, v0, v1) whose centres may lie inside ``bounds``
        (None: the whole image), clipped to the image; None if it is empty."""
        if bounds is None:
            return 0, self.width - 1, 0, self.height - 1
        u0 = max(0, math.ceil(bounds[0] - 1e-9))
        u1 = min(self.width - 1, math.floor(bounds[1] + 1e-9))
        v0 = max(0, math.ceil(bounds[2] - 1e-9))
        v1 = min(self.height - 1, math.floor(bounds[3] + 1e-9))
        if u0 > u1 or v0 > v1:
            return None
        return u0, u1, v0, v1
