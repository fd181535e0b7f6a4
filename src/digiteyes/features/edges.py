"""Edges on 1D intensity profiles: derivative, signed peaks, subpixel refinement.

For each slice the derivative of the intensity profile is computed; a peak of the
correct sign is the crossing of the slice with the finger silhouette (report Sec. 4,
thesis Sec. 4.3.1 "Fast Feature Detection").

The derivative is the central difference of the profile smoothed with ``[1, 2, 1] / 4``,
scaled so that the response to an ideal step of height ``H`` grey levels peaks at ``H``:

``e_j = (I_{j+2} + 2 I_{j+1} - 2 I_{j-1} - I_{j-2}) / 3``.

The response is therefore in grey levels and comparable with a minimum contrast, whatever
the sampling step. In each search range the strongest local maximum of the signed
response is taken and refined by the vertex of the parabola through it and its two
neighbours.

The search runs in one compiled loop over all profiles (numba): a vectorised numpy
version needed ~20 array operations on arrays of a few thousand samples, and their call
overhead, not the arithmetic, dominated (DESIGN.md Sec. 8).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

KERNEL_HALF_WIDTH = 2


def edge_response(profiles: np.ndarray) -> np.ndarray:
    """Smoothed derivative of profiles (..., J) along the last axis, in grey levels per
    sample step. The first and last ``KERNEL_HALF_WIDTH`` samples are 0."""
    p = np.asarray(profiles, dtype=np.float64)
    out = np.zeros(p.shape)
    out[..., 2:-2] = (p[..., 4:] - p[..., :-4] + 2.0 * (p[..., 3:-1] - p[..., 1:-3])) / 3.0
    return out


@dataclass(frozen=True)
class EdgeSearch:
    """Result of :func:`find_edges` for R profiles with K searches each (arrays (R, K)).

    Attributes
    ----------
    position : edge positions along the slices, px (NaN where none was found).
    height : signed response at the edge, grey levels (0 where none was found).
    before, after : intensity ``side_px`` before and after the edge along the slice (the
        two regions the edge separates; NaN where none was found).
    window_mean : mean intensity of the samples inside the image in the search range
        (NaN if there are none): what a search that found nothing saw.
    """

    position: np.ndarray
    height: np.ndarray
    before: np.ndarray
    after: np.ndarray
    window_mean: np.ndarray


@njit(cache=True, inline="always")
def smoothed_derivative(prof, response):  # pragma: no cover - compiled
    """Edge response of one profile into ``response`` (module docstring); ends are 0."""
    n = prof.shape[0]
    for j in range(min(2, n)):
        response[j] = 0.0
        response[n - 1 - j] = 0.0
    for j in range(2, n - 2):
        response[j] = (prof[j + 2] - prof[j - 2] + 2.0 * (prof[j + 1] - prof[j - 1])) / 3.0


@njit(cache=True, inline="always")
def peak_in_range(prof, inside, response, c, sign, half_window, first, step, min_contrast,
                  side_samples):  # pragma: no cover - compiled
    """Strongest local maximum of ``sign * response`` within ``c +- half_window`` (px along
    a profile whose sample j lies at ``first + j step``), refined by the parabola vertex.

    Returns ``position, height, before, after, window_mean`` as in :class:`EdgeSearch`.
    """
    n_samples = prof.shape[0]
    if not np.isfinite(c):
        return np.nan, 0.0, np.nan, np.nan, np.nan
    lo = max(int(np.ceil((c - half_window - first) / step)), 2)
    hi = min(int(np.floor((c + half_window - first) / step)), n_samples - 3)
    best = -1
    best_value = -np.inf
    total = 0.0
    count = 0
    for j in range(lo, hi + 1):
        if not inside[j]:
            continue
        total += prof[j]
        count += 1
        s = sign * response[j]
        if (s >= min_contrast and s > best_value
                and s >= sign * response[j - 1] and s > sign * response[j + 1]):
            best = j
            best_value = s
    window_mean = total / count if count > 0 else np.nan
    if best < 0:
        return np.nan, 0.0, np.nan, np.nan, window_mean
    left = sign * response[best - 1]
    mid = sign * response[best]
    right = sign * response[best + 1]
    curvature = left - 2.0 * mid + right
    delta = 0.0
    if curvature < 0.0:
        delta = min(max(0.5 * (left - right) / curvature, -0.5), 0.5)
    return (first + (best + delta) * step, best_value, prof[max(best - side_samples, 0)],
            prof[min(best + side_samples, n_samples - 1)], window_mean)


@njit(cache=True)
def _peaks_kernel(profiles, inside, centre, signs, half_window, first, step, min_contrast,
                  side_samples, position, height, before, after,
                  window_mean):  # pragma: no cover - compiled
    response = np.empty(profiles.shape[1])
    for row in range(profiles.shape[0]):
        smoothed_derivative(profiles[row], response)
        for k in range(centre.shape[1]):
            (position[row, k], height[row, k], before[row, k], after[row, k],
             window_mean[row, k]) = peak_in_range(
                profiles[row], inside[row], response, centre[row, k], signs[k], half_window,
                first, step, min_contrast, side_samples)


def find_edges(
    profiles: np.ndarray,
    inside: np.ndarray,
    centre: np.ndarray,
    signs: np.ndarray,
    offsets: np.ndarray,
    half_window: float,
    min_contrast: float,
    side_px: float = 3.0,
) -> EdgeSearch:
    """Strongest edge of the wanted sign near each predicted position, subpixel.

    Parameters
    ----------
    profiles : (R, J) intensity profiles sampled at ``offsets`` (px along each slice).
    inside : (R, J) bool, samples inside the image.
    centre : (R, K) predicted edge positions (px along the slice), K searches per
        profile; NaN skips a search.
    signs : (K,) +1 to find rising edges (intensity grows along the slice), -1 falling.
    offsets : (J,) evenly spaced sample positions, px.
    half_window : the search range is ``centre +- half_window``, px.
    min_contrast : smallest accepted response, grey levels (the step height of an edge).
    side_px : distance from the edge at which ``before`` and ``after`` are read, px.

    Returns
    -------
    EdgeSearch

    Notes
    -----
    A candidate must be a local maximum of the signed response over the whole profile
    (``s_j >= s_{j-1}`` and ``s_j > s_{j+1}``), so the flank of a strong edge just outside
    the range is never taken for an edge at the range's border. The parabola vertex
    ``delta = (s_{j-1} - s_{j+1}) / (2 (s_{j-1} - 2 s_j + s_{j+1}))`` is clipped to +-0.5
    samples.
    """
    profiles = np.ascontiguousarray(profiles, dtype=np.float64)
    centre = np.ascontiguousarray(centre, dtype=np.float64)
    out = [np.empty(centre.shape) for _ in range(5)]
    step = float(offsets[1] - offsets[0]) if len(offsets) > 1 else 1.0
    _peaks_kernel(profiles, np.ascontiguousarray(inside, dtype=np.bool_), centre,
                  np.asarray(signs, dtype=np.float64), float(half_window), float(offsets[0]),
                  step, float(min_contrast), round(side_px / step), *out)
    return EdgeSearch(*out)
