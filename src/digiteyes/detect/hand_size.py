"""The user's hand: its scale from frames of an open hand, and a personal model file.

What sets metric scale (docs/initialisation.md):

* **two or more cameras** (a calibrated rig): triangulation fixes the scale; the fit's
  ``s`` is estimated in every frame and the median kept. Error: the keypoint noise over
  the baseline, about 1-2 % for a 100 mm baseline at 500 mm.
* **one camera and a known hand length** (wrist crease to middle fingertip, measured with
  a ruler): ``s = length / model length``. Error: the measurement (a few mm of 190 mm,
  1-2 %) plus where the detector puts the wrist.
* **one camera alone**: nothing in the image sets the scale (a hand ``s`` times larger at
  ``s`` times the depth projects identically); the nominal hand is assumed. Adult hand
  lengths spread with a standard deviation of about 8 % about their mean, so the depth
  (and every metric position) carries that error.
* **one camera and a calibration object** in the hand's plane (a chessboard of known
  square size): gives the depth of that plane and hence the scale; error set by how well
  the hand stays in the plane.

With two or more cameras the 15 finger segments are also measured one by one
(:mod:`digiteyes.detect.link_lengths`) and written into the personal model.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from digiteyes.camera import Rig
from digiteyes.detect.candidate import HandDetector
from digiteyes.detect.hand21 import PALM
from digiteyes.detect.link_lengths import measured_lengths, triangulate, with_link_lengths
from digiteyes.detect.model_fit import PoseFit, palm_points
from digiteyes.detect.pose import estimate_pose
from digiteyes.errors import DigitEyesError
from digiteyes.io.safe_paths import atomic_write_bytes
from digiteyes.kinematics import KinematicModel, format_model_text
from digiteyes.kinematics.scaling import scaled_model


def model_hand_length(model: KinematicModel) -> float:
    """Wrist to middle fingertip of the model's straight hand, mm."""
    points = palm_points(model)
    return float(np.linalg.norm(points[12] - points[0]))


def scale_from_length(model: KinematicModel, hand_length_mm: float) -> float:
    """The scale that gives the model a measured hand length (wrist to middle tip, mm)."""
    if not 80.0 < hand_length_mm < 300.0:
        raise DigitEyesError(f"hand length must be a wrist-to-middle-fingertip length in mm "
                             f"(80..300), got {hand_length_mm}")
    return hand_length_mm / model_hand_length(model)


HAND_SCALE_RANGE = (0.6, 1.6)
"""Hand sizes, relative to the model file, that a measurement may return; one outside is
a detection of something else (part of the hand labelled as a whole one)."""


def palm_scale(model: KinematicModel, rig: Rig,
               keypoints: Sequence[np.ndarray | None]) -> float | None:
    """The hand's size relative to ``model`` from the palm alone: the palm's keypoints
    (:data:`~digiteyes.detect.hand21.PALM`) triangulated from the cameras that found the hand
    (``keypoints``: (21, 2) px per camera of ``rig``, None where none), and the median
    over their pairs of the distance's ratio to the model's. None with fewer than two
    cameras or fewer than three palm points triangulated.

    The palm is rigid and its keypoints are placed alike by a detector and the model;
    the fingers' keypoints sit by the detector's convention (on our flesh hand MediaPipe
    puts each fingertip 15-45 % of the distal segment short of the model's tip point;
    docs/initialisation.md, "Where the two-camera size is biased")."""
    if sum(k is not None for k in keypoints) < 2:
        return None
    points = triangulate(rig, [None if k is None else
                               np.asarray(k, dtype=float)[list(PALM)]
                               for k in keypoints])
    nominal = palm_points(model)[list(PALM)]
    seen = np.flatnonzero(np.isfinite(points).all(axis=1))
    if len(seen) < 3:
        return None
    ratios = [np.linalg.norm(points[a] - points[b]) / np.linalg.norm(nominal[a] - nominal[b])
              for i, a in enumerate(seen) for b in seen[i + 1:]]
    return float(np.median(ratios))


def scale_from_fits(fits: Sequence[PoseFit]) -> tuple[float, float, int]:
    """Median, spread (median absolute deviation, as a fraction) and count of the fitted
    scales of several frames (fits whose scale was fitted, i.e. two cameras or 3D)."""
    scales = np.array([f.scale for f in fits if f is not None and f.scale_fitted])
    if len(scales) == 0:
        raise DigitEyesError("no frame gave a fitted hand scale: the scale needs two cameras "
                             "(or give the hand length with one camera)")
    median = float(np.median(scales))
    return median, float(np.median(np.abs(scales - median)) / median), len(scales)


@dataclass(frozen=True)
class HandMeasurement:
    """The user's hand measured from image sets of a calibrated rig (:func:`measure_hand`).

    scale, spread, frames : :func:`scale_from_fits` of the per-set fits.
    lengths : the 15 finger segments (mm, :data:`~digiteyes.detect.link_lengths.SEGMENT_NAMES`
        order), the median over the sets of the triangulated keypoints; None when not
        measured (``segments=False``, or a detector that does not locate joints).
    segment_frames : per segment, the sets that measured it (None with ``lengths``).
    """

    scale: float
    spread: float
    frames: int
    lengths: np.ndarray | None
    segment_frames: np.ndarray | None


def measure_hand(image_sets: Iterable[Sequence[np.ndarray]], rig: Rig,
                 detector: HandDetector, model: KinematicModel,
                 segments: bool = True, side: str | None = None) -> HandMeasurement:
    """Measure the hand in image sets (one image per camera of ``rig``, at the same moment):
    the scale of the model fitted to each set's detections, and, with ``segments`` and a
    detector that locates joints (``detector.locates_joints``), the finger segments of
    the keypoints triangulated in each set seen by two or more cameras. ``side``: of
    several hands in an image, the one of that side (:mod:`digiteyes.detect.side`; None:
    the most confident). Raises :class:`DigitEyesError` when no set gives a fitted scale
    or a segment is never seen."""
    fits, points, other_sides = [], [], 0
    for images in image_sets:
        result = estimate_pose(list(images), rig, detector, model, side=side)
        fits.append(result.fit)
        other_sides += result.other_hands > 0
        seen = [None if c is None else c.keypoints for c in result.candidates]
        if sum(k is not None for k in seen) >= 2:
            points.append(triangulate(rig, seen))
    if other_sides and all(fit is None for fit in fits):
        raise DigitEyesError(f"no image set shows a hand of the side asked for; the detector "
                             f"saw one of the other side in {other_sides} (calibrate-hand "
                             "--hand: the side of the hand in the images)")
    scale, spread, count = scale_from_fits(fits)
    if not (segments and detector.locates_joints):
        return HandMeasurement(scale, spread, count, None, None)
    lengths, frames = measured_lengths(np.array(points).reshape(-1, 21, 3))
    return HandMeasurement(scale, spread, count, lengths, frames)


def write_personal_model(model: KinematicModel, scale: float, path: str | Path,
                         name: str = "my-hand",
                         lengths: np.ndarray | None = None,
                         source: str = "digiteyes calibrate-hand") -> KinematicModel:
    """Write ``model`` scaled by ``scale`` as a model file, with the 15 digit segments set
    to ``lengths`` (mm, :data:`~digiteyes.detect.link_lengths.SEGMENT_NAMES` order) when
    given; ``source`` names the writer in the file's header; returns the personal
    model."""
    personal = scaled_model(model, scale, name=name)
    if lengths is not None:
        personal = with_link_lengths(personal, lengths)
    text = format_model_text(personal.spec)
    header = (f"# personal hand model written by {source}: {model.name} "
              f"scaled by {scale:.4f} (hand length {model_hand_length(personal):.1f} mm"
              f"{', measured finger segments' if lengths is not None else ''})\n")
    atomic_write_bytes(path, (header + text).encode("utf-8"))
    return personal


__all__ = ["HandMeasurement", "measure_hand", "model_hand_length", "scale_from_fits",
           "scale_from_length", "write_personal_model"]
