"""Trackers: one interface (``reset``, ``step`` -> :class:`TrackResult`) for all of them.

:class:`FeatureTracker` is DigitEyes (thesis Sec. 2.5, 4.3): point and line features,
stabilised Gauss-Newton, several cameras stacked in one system.
:class:`DivideConquerTracker` is Huang, Wu & Lin's (palm by ICP, fingers by SMC), with
its baselines :class:`CondensationTracker` and :class:`RandomSearchTracker`.
"""

from digiteyes.trackers.base import TIMING_STAGES, Tracker, TrackResult
from digiteyes.trackers.divide_conquer import (
    CondensationTracker,
    DivideConquerDetails,
    DivideConquerOptions,
    DivideConquerTracker,
    RandomSearchTracker,
)
from digiteyes.trackers.feature_tracker import (
    THESIS_EXCLUDED_LINKS,
    FeatureTracker,
    FeatureTrackerOptions,
    all_features,
    thesis_whole_hand_links,
)
from digiteyes.trackers.parameterisation import StateParameterisation
from digiteyes.trackers.prediction import StatePredictor

__all__ = [
    "THESIS_EXCLUDED_LINKS", "TIMING_STAGES", "CondensationTracker", "DivideConquerDetails",
    "DivideConquerOptions", "DivideConquerTracker", "FeatureTracker", "FeatureTrackerOptions",
    "RandomSearchTracker",
    "StateParameterisation", "StatePredictor", "TrackResult", "Tracker",
    "all_features", "thesis_whole_hand_links",
]
