"""DigitEyes feature measurement: slices, edge peaks, link lines, tip points, residuals.

``measure_features`` places the T-shaped link trackers and the tip trackers of the report
(Sec. 4) at the predicted projection of the model and measures link axis lines and tip
points; ``feature_residuals`` turns them into the residual vector and its analytic
Jacobian (thesis eq. 2.17-2.20, report eq. 2-3, 6-10);
:mod:`~digiteyes.features.width_scale` measures the user's link widths on a frame whose
state is known. See docs/features.md.
"""

from digiteyes.features.lines import LineFit, bisector, fit_lines
from digiteyes.features.measure import (
    LINK_REASONS,
    TIP_REASONS,
    FeatureMeasurement,
    FeatureOptions,
    measure_features,
    project_features,
)
from digiteyes.features.residuals import ResidualLayout, feature_residuals
from digiteyes.features.slices import prepare_image, sample_profiles

__all__ = [
    "LINK_REASONS", "TIP_REASONS", "FeatureMeasurement", "FeatureOptions", "LineFit",
    "ResidualLayout", "bisector", "feature_residuals", "fit_lines", "measure_features",
    "prepare_image", "project_features", "sample_profiles",
]
