"""The layered-template benchmark: each row says which appearance it was drawn in, and
the independent flesh hand is tracked by the same code path as our own drawing."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.benchmarks.templates import track_scenario
from digiteyes.trackers import LayeredTemplateOptions


@pytest.mark.parametrize("appearance", ["model", "flesh"])
def test_a_short_two_finger_run_in_each_appearance(appearance):
    row = track_scenario("two-finger-occlusion", 1, 6, LayeredTemplateOptions(),
                         "templates+features", appearance)
    assert row["appearance"] == appearance and row["frames"] == 6
    assert np.isfinite(row["mean_tip_error_mm"])
    assert row["mean_tip_error_mm"] < 10.0  # the first frames, before the occlusion
    assert row["middle_max_deviation_rad"] < 0.2
    # the worst frame is over frames (the mean over the tips of each), not over tips
    assert len(row["tip_error_per_frame_mm"]) == 6
    assert row["max_frame_tip_error_mm"] == pytest.approx(max(row["tip_error_per_frame_mm"]),
                                                          abs=0.01)
