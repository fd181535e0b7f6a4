"""Initialisation: hand detectors behind one protocol and the model fit to their keypoints.

* :mod:`~digiteyes.detect.hand21` the 21 keypoints and their place on the model;
* :mod:`~digiteyes.detect.candidate` :class:`HandCandidate` and the :class:`HandDetector`
  protocol;
* :mod:`~digiteyes.detect.mediapipe_detector` MediaPipe Hands (optional extra);
* :mod:`~digiteyes.detect.classic` a detector with no learned parts (plain backgrounds);
* :mod:`~digiteyes.detect.fallback` one detector, and another where the first finds none
  (what ``--init auto`` runs with MediaPipe installed);
* :mod:`~digiteyes.detect.side` which of several detected hands is the tracked one;
* :mod:`~digiteyes.detect.model_fit` the kinematic model fitted to keypoints.
"""

from digiteyes.detect.candidate import HandCandidate, HandDetector
from digiteyes.detect.hand21 import HAND21_NAMES
from digiteyes.detect.model_fit import FitOptions, KeypointObservation, PoseFit, fit_keypoints

__all__ = ["HAND21_NAMES", "FitOptions", "HandCandidate", "HandDetector",
           "KeypointObservation", "PoseFit", "fit_keypoints"]
