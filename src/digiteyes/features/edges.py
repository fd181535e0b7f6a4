"""Edges on 1D intensity profiles: derivative, signed peaks, subpixel refinement.

For each slice the derivative of the intensity profile is computed; a peak of the
correct sign is the crossing of the slice with the finger silhouette (report Sec. 4,
thesis Sec. 4.3.1 "Fast Feature Detection").

The derivative is the central difference of the profile smoothed with ``[1, 2, 1] / 4``,
scaled so that the response to an ideal step of height ``H`` grey levels peaks at ``H``:

``e_j = (I_{j+2} + 2 I_{j+1} - 2 I_{j-1} - I_{j-2}) / 3``.

The response is therefore in grey levels and comparable with a minimum contrast, whatever
the sampling step. Peaks are refined by fitting a parabola through the peak sample and
its two neighbours. All functions work on arrays (..., J) of profiles at once.
"""

from __future__ import annotations

import numpy as np

KERNEL_HALF_WIDTH = 2


def edge_response(profiles: np.ndarray) -> np.ndarray:
    """Smoothed derivative of profiles (..., J) along the last axis, in grey levels.

    The first and last ``KERNEL_HALF_WIDTH`` samples, where the kernel does not fit, are 0.
    """
    p = np.asarray(profiles, dtype=np.float32)
    out = np.zeros(p.shape, dtype=np.float32)
    out[..., 2:-2] = (p[..., 4:] - p[..., :-4] + 2.0 * (p[..., 3:-1] - p[..., 1:-3])) / 3.0
    return out


def strongest_peaks(
    strength: np.ndarray, allowed: np.ndarray, min_contrast: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Strongest local maximum of ``strength`` inside ``allowed``, refined to subpixel.

    Parameters
    ----------
    strength : (..., J) signed edge response, already multiplied by the sign expected for
        the wanted edge (so the wanted edge is a positive peak).
    allowed : (..., J) bool, samples inside the search range (and the image).
    min_contrast : smallest accepted peak height, grey levels.

    Returns
    -------
    position : (...,) peak position in samples (float, NaN when not found).
    found : (...,) bool.
    height : (...,) response at the peak sample (grey levels).

    Notes
    -----
    A candidate must be a local maximum over the whole profile (``s_j >= s_{j-1}`` and
    ``s_j > s_{j+1}``), so that the slope of a strong edge just outside the search range
    is never taken for an edge at the range's border. The parabola vertex
    ``delta = (s_{j-1} - s_{j+1}) / (2 (s_{j-1} - 2 s_j + s_{j+1}))`` is clipped to
    +-0.5 samples.
    """
    s = strength
    local_max = np.zeros(s.shape, dtype=bool)
    local_max[..., 1:-1] = (s[..., 1:-1] >= s[..., :-2]) & (s[..., 1:-1] > s[..., 2:])
    candidates = allowed & local_max & (s >= min_contrast)
    masked = np.where(candidates, s, -np.inf)
    j = np.argmax(masked, axis=-1)
    found = np.take_along_axis(candidates, j[..., None], axis=-1)[..., 0]
    j = np.clip(j, 1, s.shape[-1] - 2)
    left = np.take_along_axis(s, (j - 1)[..., None], axis=-1)[..., 0]
    centre = np.take_along_axis(s, j[..., None], axis=-1)[..., 0]
    right = np.take_along_axis(s, (j + 1)[..., None], axis=-1)[..., 0]
    curvature = left - 2.0 * centre + right
    with np.errstate(invalid="ignore", divide="ignore"):
        delta = np.where(curvature < 0.0, 0.5 * (left - right) / curvature, 0.0)
    position = j + np.clip(delta, -0.5, 0.5)
    return np.where(found, position, np.nan), found, centre
