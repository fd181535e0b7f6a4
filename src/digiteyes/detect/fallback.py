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
"""

from __future__ import annotations

import numpy as np

from digiteyes.camera import Camera
from digiteyes.detect.candidate import HandCandidate, HandDetector

MIN_FALLBACK_CONFIDENCE = 0.7
"""Confidence a candidate of the second detector needs to be returned."""


class FallbackDetector:
    """``primary``'s candidates; when it finds none, those of ``fallback`` with a confidence
    of at least ``min_confidence``. Each candidate names the detector that found it
    (:attr:`HandCandidate.detector`)."""

    def __init__(self, primary: HandDetector, fallback: HandDetector,
                 min_confidence: float = MIN_FALLBACK_CONFIDENCE) -> None:
        self.primary, self.fallback = primary, fallback
        self.min_confidence = float(min_confidence)
        self.name = f"{primary.name}, else {fallback.name}"
        self.locates_joints = primary.locates_joints and fallback.locates_joints

    def detect(self, image: np.ndarray, camera: Camera | None = None) -> list[HandCandidate]:
        """Hand candidates in ``image``, best first (see the class docstring)."""
        found = self.primary.detect(image, camera)
        if found:
            return found
        return [c for c in self.fallback.detect(image, camera)
                if c.confidence >= self.min_confidence]
