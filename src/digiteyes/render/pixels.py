"""Pixel grids: the distortion-free part of a camera that the ray caster samples.

A :class:`PixelGrid` holds the intrinsics, projection model and size of an image, possibly
supersampled or enlarged into a canvas (for lens distortion). The ray through pixel
(u, v) is the one :meth:`digiteyes.camera.Camera.viewing_rays` gives (see
:mod:`digiteyes.render._kernels` for the camera-frame form used).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from digiteyes.camera import Camera


@dataclass(frozen=True)
class PixelGrid:
    """Pixel-to-ray map of an image of ``width`` x ``height`` pixels.

    ``K`` (3, 3) follows :class:`~digiteyes.camera.Camera` (pixels per mm for the
    orthographic model); ``scale`` is 1 for perspective and orthographic cameras and
    ``1 / depth_mm`` for scaled-orthographic ones.
    """

    perspective: bool
    K: np.ndarray
    width: int
    height: int
    scale: float = 1.0

    @classmethod
    def from_camera(cls, cam: Camera) -> PixelGrid:
        """The grid of a camera's image, ignoring lens distortion."""
        scale = 1.0 / cam.depth_mm if cam.projection == "scaled-orthographic" else 1.0
        return cls(cam.projection == "perspective", np.array(cam.K, dtype=float),
                   cam.width, cam.height, scale)

    @property
    def intrinsics(self) -> np.ndarray:
        """(fx, s, cx, fy, cy)."""
        return np.array([self.K[0, 0], self.K[0, 1], self.K[0, 2], self.K[1, 1], self.K[1, 2]])

    def supersampled(self, factor: int) -> PixelGrid:
        """The grid with ``factor`` x ``factor`` samples per pixel: sample (i, j) of pixel
        (u, v) sits at ``(u + (i + 0.5) / factor - 0.5, v + (j + 0.5) / factor - 0.5)``, so
        the mean of each block of samples is the pixel."""
        K = self.K.copy()
        K[:2] *= factor
        K[:2, 2] += 0.5 * (factor - 1)
        return PixelGrid(self.perspective, K, self.width * factor, self.height * factor,
                         self.scale)

    def canvas(self, u_min: int, v_min: int, width: int, height: int) -> PixelGrid:
        """A grid of ``width`` x ``height`` whose pixel (0, 0) is this grid's (u_min, v_min)."""
        K = self.K.copy()
        K[0, 2] -= u_min
        K[1, 2] -= v_min
        return PixelGrid(self.perspective, K, width, height, self.scale)
