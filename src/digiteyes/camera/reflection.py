"""The reflection ``S = diag(-1, 1, 1)`` that maps a scene to its mirror image and back,
on points and on pixels of images flipped left to right (:mod:`digiteyes.camera.mirror`
builds the mirrored cameras on it; :class:`~digiteyes.camera.Rig` maps outputs back)."""

from __future__ import annotations

import numpy as np

REFLECTION = np.array([-1.0, 1.0, 1.0])
"""The diagonal of ``S``, the reflection in the y-z plane (x -> -x)."""


def unmirror_pixels(uv: np.ndarray, width: int) -> np.ndarray:
    """Pixel positions (..., 2) in a flipped image of ``width`` px, in the original image
    (pixel centres at integer coordinates: ``u -> W - 1 - u``)."""
    out = np.array(uv, dtype=float)
    out[..., 0] = width - 1 - out[..., 0]
    return out


def unmirror_points(xyz: np.ndarray) -> np.ndarray:
    """Points (..., 3) of the reflected scene (any camera's frame or the world), in the
    real one: ``x`` changes sign."""
    return np.asarray(xyz, dtype=float) * REFLECTION
