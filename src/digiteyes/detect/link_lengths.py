"""The user's finger link lengths from keypoints seen by two or more calibrated cameras.

Thesis Sec. 2.2.3 gives each user's hand its own kinematic parameters and Ch. 6 names
their estimation as future work. With a calibrated rig the detected 2D keypoints of one
frame are triangulated (:func:`triangulate`: the point closest, in the least-squares
sense, to the viewing rays of every camera that saw it), and the 15 digit segments
(:data:`DIGIT_SEGMENTS`: per digit base -> joint -> joint -> tip) are measured in every
frame; the median over frames is robust to a frame whose detection slipped.

:func:`with_link_lengths` then sets those lengths on the model. Between two consecutive
keypoints of a digit lie the DH rows from the first keypoint's link to the parent of the
second's (one row on the shipped hand: the link's own ``a``); the distance between the
two keypoints is ``sqrt(a^2 + d^2)`` summed along those rows, plus, for a fingertip, the
fixed offset of the tip point on the end sphere (:func:`~digiteyes.detect.hand21.model_anchors`).
The rows' constant ``a`` and ``d`` are multiplied by the one factor that gives the measured
length; the joint angles, radii and the palm are left alone. The lengths a detector
reports follow its own convention for where a joint lies, and its errors are those of
the keypoints (docs/initialisation.md measures them on the STB stereo pair).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from digiteyes.camera import Rig
from digiteyes.detect.hand21 import HAND21_NAMES, model_anchors
from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import KinematicModel

DIGIT_SEGMENTS: tuple[tuple[int, int], ...] = tuple(
    (1 + 4 * digit + j, 2 + 4 * digit + j) for digit in range(5) for j in range(3))
"""The 15 segments (pairs of indices into the 21 keypoints), thumb to little finger,
each digit base to tip."""
SEGMENT_NAMES: tuple[str, ...] = tuple(f"{HAND21_NAMES[i]}-{HAND21_NAMES[j].split('.')[1]}"
                                       for i, j in DIGIT_SEGMENTS)
"""Names of the segments, e.g. ``index.mcp-pip``."""


def triangulate(rig: Rig, keypoints: Sequence[np.ndarray | None]) -> np.ndarray:
    """World points (K, 3) mm from pixel keypoints (K, 2) per camera of ``rig`` (None for
    a camera that found no hand; NaN rows for a point it did not see). Each point is the
    least-squares closest point to the viewing rays of the cameras that saw it; NaN where
    fewer than two did."""
    if len(keypoints) != len(rig):
        raise DigitEyesError(f"triangulate needs one keypoint array per camera ({len(rig)}), "
                             f"got {len(keypoints)}")
    seen = [(cam, np.asarray(k, dtype=float)) for cam, k in zip(rig, keypoints, strict=True)
            if k is not None]
    if not seen:
        raise DigitEyesError("triangulate needs keypoints from at least two cameras, got none")
    n = len(seen[0][1])
    A = np.zeros((n, 3, 3))
    b = np.zeros((n, 3))
    count = np.zeros(n, dtype=int)
    for cam, pixels in seen:
        if pixels.shape != (n, 2):
            raise DigitEyesError(f"keypoints of camera {cam.name!r} have shape {pixels.shape}, "
                                 f"expected ({n}, 2)")
        ok = np.isfinite(pixels).all(axis=1)
        origins, directions = cam.viewing_rays(np.where(ok[:, None], pixels, 0.0))
        # (I - d d^T) projects onto the plane normal to the ray.
        P = np.eye(3) - directions[:, :, None] * directions[:, None, :]
        A[ok] += P[ok]
        b[ok] += np.einsum("kij,kj->ki", P, origins)[ok]
        count += ok
    out = np.full((n, 3), np.nan)
    solvable = count >= 2
    if solvable.any():
        out[solvable] = np.linalg.solve(A[solvable], b[solvable][..., None])[..., 0]
    return out


def segment_lengths(points: np.ndarray) -> np.ndarray:
    """Lengths (..., 15) mm of :data:`DIGIT_SEGMENTS` for keypoints (..., 21, 3) mm."""
    points = np.asarray(points, dtype=float)
    i, j = np.array(DIGIT_SEGMENTS).T
    return np.linalg.norm(points[..., j, :] - points[..., i, :], axis=-1)


def measured_lengths(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per segment the median length over frames (15,) mm and the number of frames that
    measured it, from triangulated keypoints (F, 21, 3) (NaN where missing)."""
    lengths = segment_lengths(np.asarray(points, dtype=float).reshape(-1, 21, 3))
    counts = np.isfinite(lengths).sum(axis=0)
    if (counts == 0).any():
        missing = [SEGMENT_NAMES[s] for s in np.flatnonzero(counts == 0)]
        raise DigitEyesError(f"no frame measured the segment(s) {', '.join(missing)}: they "
                             "need keypoints seen by two cameras")
    return np.nanmedian(lengths, axis=0), counts


def _segment_rows(model: KinematicModel, start: int, end: int) -> list[int]:
    """The DH rows from ``start`` (inclusive) to the parent of ``end``, walking up the tree
    from ``end``."""
    rows, row = [], int(model.parent[end])
    while row != start:
        if row < 0:
            raise DigitEyesError(f"model {model.name!r}: row {end} does not descend from row "
                                 f"{start}")
        rows.append(row)
        row = int(model.parent[row])
    return [*rows, start]


def model_lengths(model: KinematicModel) -> np.ndarray:
    """The model's own lengths (15,) mm of :data:`DIGIT_SEGMENTS`."""
    rows, points = model_anchors(model)
    out = []
    for i, j in DIGIT_SEGMENTS:
        chain = sum(np.hypot(model.a[r], model.d[r]) for r in _segment_rows(model, rows[i],
                                                                          rows[j]))
        out.append(chain + np.linalg.norm(points[j]))
    return np.array(out)


def with_link_lengths(model: KinematicModel, lengths: np.ndarray,
                      name: str | None = None) -> KinematicModel:
    """A copy of ``model`` whose 15 digit segments have ``lengths`` (15,) mm (see the
    module docstring). Raises :class:`DigitEyesError` for a length the model cannot take
    (not longer than the tip's fixed offset)."""
    lengths = np.asarray(lengths, dtype=float)
    if lengths.shape != (len(DIGIT_SEGMENTS),) or not np.isfinite(lengths).all():
        raise DigitEyesError(f"link lengths must be {len(DIGIT_SEGMENTS)} finite numbers "
                             f"(mm), got shape {lengths.shape}")
    rows, points = model_anchors(model)
    factor = np.ones(model.n_frames)
    for (i, j), length, label in zip(DIGIT_SEGMENTS, lengths, SEGMENT_NAMES, strict=True):
        path = _segment_rows(model, rows[i], rows[j])
        chain = sum(np.hypot(model.a[r], model.d[r]) for r in path)
        offset = float(np.linalg.norm(points[j]))
        if not length > offset or chain <= 0.0:
            raise DigitEyesError(f"segment {label}: {length:.1f} mm cannot be set on model "
                                 f"{model.name!r} (its fixed part is {offset:.1f} mm)")
        factor[path] = (length - offset) / chain
    frames = []
    for row in model.spec.frames:
        f = factor[row.index]
        d = row.d if row.d_state is not None else f * row.d
        frames.append(dataclasses.replace(row, a=f * row.a, d=d))
    spec = dataclasses.replace(model.spec, frames=tuple(frames),
                               description=f"{model.description} (own link lengths)")
    if name is not None:
        spec = dataclasses.replace(spec, name=name)
    return KinematicModel(spec)


__all__ = ["DIGIT_SEGMENTS", "SEGMENT_NAMES", "measured_lengths", "model_lengths",
           "segment_lengths", "triangulate", "with_link_lengths"]
