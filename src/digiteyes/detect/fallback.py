"""Two detectors in turn: the first one's hands, else the second one's confident ones.

``--init auto``, the recovery after a lost frame and ``pose`` use MediaPipe when it is
installed (:func:`~digiteyes.detect.pose.make_detector` with ``classic_fallback``).
MediaPipe misses some hands a plain background shows plainly (docs/initialisation.md: the
palm-on, back-lit webcam render of the flesh hand), and then a run could not start at all.
:class:`FallbackDetector` asks the classic detector in exactly those images, and keeps its
candidate only when the silhouette gave every digit a consistent label (confidence at
least :data:`MIN_FALLBACK_CONFIDENCE`). On the cluttered annotated photographs where
MediaPipe finds no hand (docs/real-data.md) the classic candidates score 0.0-0.57; on the
first frames of the flesh hand's webcam, desk and egocentric renders, 0.73-0.86.

In that dim webcam render MediaPipe also returns hands it has only partly recognised: a
confidence of 0.51-0.69, and keypoints that span 150-200 px where the hand's silhouette
spans 470 (the classic detector's keypoints). Fitted at the model's size, such a hand is
placed 300 mm too far (one of eight seeds of ``bench auto-start``). So a first-detector
hand below :data:`MIN_PRIMARY_CONFIDENCE` also asks the second detector. A confident
hand of the second whose keypoints span between :data:`PARTIAL_SPAN_RATIO` times as
much and :data:`MAX_SPAN_RATIO` times (the webcam renders: 2.4-3.1) then comes first.
Beyond that the silhouette is not this hand alone: in a whole-body photograph of the
annotated images (panoptic) MediaPipe finds a hand of 79 px at 0.55 while the classic
detector labels the person's silhouette, 1329 px, at 0.73. On the real video MediaPipe's
confidence is 0.86-0.99 (every tenth frame), and on the desk renders 0.98, so there
nothing changes.
"""

from __future__ import annotations

import numpy as np

from digiteyes.camera import Camera
from digiteyes.detect.candidate import HandCandidate, HandDetector, bbox_of

MIN_FALLBACK_CONFIDENCE = 0.7
"""Confidence a candidate of the second detector needs to be returned."""
MIN_PRIMARY_CONFIDENCE = 0.8
"""Below this confidence the first detector's best hand is checked against the second's."""
PARTIAL_SPAN_RATIO = 1.5
"""A second-detector hand whose keypoints span more than this times the first detector's
best hand shows that the first one labelled only part of the hand."""
MAX_SPAN_RATIO = 4.0
"""...unless they span more than this times as much: then the second detector's
silhouette is more than the hand (an arm, a body)."""


def keypoint_span(candidate: HandCandidate) -> float:
    """The diagonal (px) of the box that holds ``candidate``'s keypoints."""
    points = np.asarray(candidate.keypoints, dtype=float)
    points = points[np.isfinite(points).all(axis=1)]
    if not len(points):
        return 0.0
    x0, y0, x1, y1 = bbox_of(points)
    return float(np.hypot(x1 - x0, y1 - y0))


class FallbackDetector:
    """``primary``'s candidates; when it finds none, those of ``fallback`` with a confidence
    of at least ``min_confidence``, and when its best is less confident than
    ``min_primary_confidence``, a confident ``fallback`` candidate first if it spans
    :data:`PARTIAL_SPAN_RATIO` to :data:`MAX_SPAN_RATIO` times as much (module
    docstring). Each candidate names the detector that found it
    (:attr:`HandCandidate.detector`)."""

    def __init__(self, primary: HandDetector, fallback: HandDetector,
                 min_confidence: float = MIN_FALLBACK_CONFIDENCE,
                 min_primary_confidence: float = MIN_PRIMARY_CONFIDENCE) -> None:
        self.primary, self.fallback = primary, fallback
        self.min_confidence = float(min_confidence)
        self.min_primary_confidence = float(min_primary_confidence)
        self.name = f"{primary.name}, else {fallback.name}"
        self.locates_joints = primary.locates_joints and fallback.locates_joints

    def detect(self, image: np.ndarray, camera: Camera | None = None) -> list[HandCandidate]:
        """Hand candidates in ``image``, best first (see the class docstring)."""
        found = self.primary.detect(image, camera)
        if found and found[0].confidence >= self.min_primary_confidence:
            return found
        others = [c for c in self.fallback.detect(image, camera)
                  if c.confidence >= self.min_confidence]
        if not found:
            return others
        if others and (PARTIAL_SPAN_RATIO * keypoint_span(found[0]) < keypoint_span(others[0])
                       <= MAX_SPAN_RATIO * keypoint_span(found[0])):
            return [others[0], *found]
        return found
