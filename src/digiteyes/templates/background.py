"""The background template of a static camera (Rehg thesis Sec. 4.4.2).

The layered template error of :mod:`digiteyes.templates.layered` counts template pixels
only: a part that slides off the image region it covers loses nothing for the pixels it
leaves behind, and a half-hidden part can drift onto its occluder's edges at no cost.
The thesis suggests a background template for a static camera, so that every image
pixel near the hand is explained by some template (the image-domain reading of eq. 3.7).
Here the background is the LoG-filtered first frame at the pixels that no window covers
there (outlines grown by the occlusion margin); for a fixed set of image pixels ``u``
around the hand,

    E_B(q) = 1/2 sum_u w_u V_B(q, u) [I(u) - B(u)]^2,   V_B = prod_j [1 - M_j(q, u)],

the background seen through every part's window. ``I(u) - B(u)`` does not depend on the
state, so ``E_B`` has only boundary terms (eq. 3.12): a window moving off pixels that
still show the hand reveals background that does not match (``E_B`` rises), one moving
onto background pixels covers a perfect match. It needs smooth windows (unit windows
have no boundary gradient) and a camera that does not move. Pixels hidden by the hand on
the first frame are unknown (weight 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from digiteyes.occlusion.windows import ImageWindows
from digiteyes.templates._kernels import background_kernel


@dataclass(frozen=True)
class BackgroundTemplate:
    """``values`` (H, W) float32: the filtered first frame; ``known`` (H, W) bool: where
    it shows the background (no window covered it)."""

    values: np.ndarray
    known: np.ndarray


@dataclass(frozen=True)
class BackgroundEvaluation:
    """``energy`` ``E_B``; ``gradient`` (n_v,) ``dE_B/dv`` (boundary terms only);
    ``residuals``, ``visibility`` (B,) ``r`` and ``V_B`` at ``pixels`` (B, 2) int."""

    energy: float
    gradient: np.ndarray
    residuals: np.ndarray
    visibility: np.ndarray
    pixels: np.ndarray


def window_region(windows: ImageWindows, shape: tuple[int, int], pad_px: float
                  ) -> np.ndarray:
    """Integer pixels (B, 2) (column, row) of the box around all ``windows`` grown by
    ``pad_px``, clipped to an image of ``shape`` (H, W)."""
    box = windows.bounds()
    u0, v0 = np.floor(box[:, :2].min(axis=0) - pad_px).astype(int)
    u1, v1 = np.ceil(box[:, 2:].max(axis=0) + pad_px).astype(int)
    h, w = shape
    u0, v0, u1, v1 = max(u0, 0), max(v0, 0), min(u1, w - 1), min(v1, h - 1)
    if u1 < u0 or v1 < v0:
        return np.zeros((0, 2), dtype=np.int64)
    cols, rows = np.meshgrid(np.arange(u0, u1 + 1), np.arange(v0, v1 + 1))
    return np.stack([cols.ravel(), rows.ravel()], axis=1).astype(np.int64)


def acquire_background(image: np.ndarray, windows: ImageWindows, margin: float,
                       pad_px: float = 20.0) -> BackgroundTemplate:
    """The background of a filtered first frame ``image`` (H, W) whose windows (at the
    known state) are ``windows``: known where every window, grown by ``margin`` px plus
    one more pixel, leaves the pixel uncovered."""
    values = np.asarray(image, dtype=np.float32)
    pixels = window_region(windows, values.shape, pad_px)
    known = np.ones(values.shape, dtype=bool)
    ev = evaluate_background(BackgroundTemplate(values, known), values, windows, 0.0,
                             margin + 1.0, pixels)
    known[pixels[:, 1], pixels[:, 0]] = ev.visibility >= 1.0
    return BackgroundTemplate(values, known)


def evaluate_background(background: BackgroundTemplate, image: np.ndarray,
                        windows: ImageWindows, tau: float, margin: float,
                        pixels: np.ndarray) -> BackgroundEvaluation:
    """``E_B`` and its gradient (module docstring) over ``pixels`` (B, 2) int (column,
    row; held fixed over a frame), for the filtered ``image`` and the parts' ``windows``
    with their Jacobians; ``tau`` the window width (0: unit windows, no gradient)."""
    n = len(pixels)
    cols, rows = pixels[:, 0], pixels[:, 1]
    values = np.ascontiguousarray(background.values[rows, cols], dtype=np.float64)
    weights = background.known[rows, cols].astype(np.float64)
    K = len(windows.kind)
    b_pts, b_r = np.zeros((K, 4, 2)), np.zeros(K)
    r, V = np.empty(n), np.empty(n)
    energy = background_kernel(np.ascontiguousarray(image, dtype=np.float32),
                               np.ascontiguousarray(pixels), values, weights, windows.kind,
                               windows.points, windows.radius, float(tau), float(margin),
                               b_pts, b_r, r, V)
    gradient = np.einsum("kqcn,kqc->n", windows.d_points, b_pts) + b_r @ windows.d_radius
    return BackgroundEvaluation(float(energy), gradient, r, V, pixels)
