"""Trackers: one interface (``reset``, ``step`` -> :class:`TrackResult`) and a registry.

:class:`FeatureTracker` is DigitEyes (thesis Sec. 2.5, 4.3): point and line features,
stabilised Gauss-Newton, several cameras stacked in one system; registered as
``"features"``. The layered template trackers (thesis Ch. 3) are ``"templates"`` and
``"templates+features"``; :class:`DivideConquerTracker` is Huang, Wu & Lin's divide and
conquer (``"divide-conquer"``), with its baselines ``"condensation"`` and
``"random-search"``. :func:`create_tracker` builds any registered tracker by name.
"""

from digiteyes.features.selection import (
    THESIS_EXCLUDED_LINKS,
    all_features,
    thesis_whole_hand_links,
)
from digiteyes.trackers.anchored_features import (
    AnchoredFeatureOptions,
    AnchoredFeatureTracker,
)
from digiteyes.trackers.base import (
    Tracker,
    TrackResult,
    residual_unit,
    restart,
    sizes_hand,
    warm_up,
)
from digiteyes.trackers.divide_conquer import (
    CondensationOptions,
    CondensationTracker,
    DivideConquerDetails,
    DivideConquerOptions,
    DivideConquerTracker,
    RandomSearchOptions,
    RandomSearchTracker,
)
from digiteyes.trackers.feature_tracker import (
    FeatureDetails,
    FeatureTracker,
    FeatureTrackerOptions,
)
from digiteyes.trackers.keypoint_tracker import (
    KeypointDetails,
    KeypointTracker,
    KeypointTrackerOptions,
)
from digiteyes.trackers.layered_templates import (
    LayeredFeatureTracker,
    LayeredTemplateOptions,
    LayeredTemplateTracker,
    TemplateDetails,
)
from digiteyes.trackers.parameterisation import StateParameterisation
from digiteyes.trackers.prediction import StatePredictor
from digiteyes.trackers.registry import (
    TrackerEntry,
    TrackerError,
    create_tracker,
    register_tracker,
    tracker_entry,
    tracker_names,
)

DEFAULT_TRACKER = "features"

register_tracker(DEFAULT_TRACKER, FeatureTracker, FeatureTrackerOptions,
                 "DigitEyes: point and line features, stabilised Gauss-Newton "
                 "(thesis Sec. 4.3)")
register_tracker("templates", LayeredTemplateTracker, LayeredTemplateOptions,
                 "layered templates with predicted visibility order (thesis Ch. 3, "
                 "Sec. 4.4)")
register_tracker("templates+features", LayeredFeatureTracker, LayeredTemplateOptions,
                 "layered templates plus edge features of unoccluded links (thesis Ch. 3 "
                 "and Sec. 2.5)")

register_tracker("divide-conquer", DivideConquerTracker, DivideConquerOptions,
                 "Huang, Wu & Lin: palm by ICP, fingers by SMC on the manifolds between "
                 "basis configurations")
register_tracker("condensation", CondensationTracker, CondensationOptions,
                 "baseline (Huang Sec. 6): CONDENSATION in the PCA space, 3000 samples")
register_tracker("random-search", RandomSearchTracker, RandomSearchOptions,
                 "baseline (Huang Sec. 6): random search in the PCA space, 5000 samples")
register_tracker("keypoints", KeypointTracker, KeypointTrackerOptions,
                 "ours: the model fitted every frame to a learned detector's keypoints "
                 "(MediaPipe when installed), from the previous estimate")
register_tracker("features+keypoints", AnchoredFeatureTracker, AnchoredFeatureOptions,
                 "ours: the feature tracker with MediaPipe's keypoints in every solve "
                 "(needs the mediapipe extra)")

__all__ = [
    "DEFAULT_TRACKER", "THESIS_EXCLUDED_LINKS", "AnchoredFeatureOptions",
    "AnchoredFeatureTracker", "CondensationOptions", "CondensationTracker",
    "DivideConquerDetails", "DivideConquerOptions", "DivideConquerTracker", "FeatureDetails",
    "FeatureTracker", "FeatureTrackerOptions", "KeypointDetails", "KeypointTracker",
    "KeypointTrackerOptions", "LayeredFeatureTracker", "LayeredTemplateOptions",
    "LayeredTemplateTracker", "RandomSearchOptions", "RandomSearchTracker",
    "StateParameterisation", "StatePredictor", "TemplateDetails", "TrackResult", "Tracker",
    "TrackerEntry", "TrackerError", "all_features", "create_tracker", "register_tracker",
    "residual_unit", "restart", "sizes_hand", "thesis_whole_hand_links", "tracker_entry",
    "tracker_names", "warm_up",
]
