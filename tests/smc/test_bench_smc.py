"""``digiteyes bench smc`` pieces on a tiny run (figures finite, accuracy sane)."""

import math

from digiteyes.benchmarks import smc
from digiteyes.trackers.divide_conquer import DivideConquerTracker


def test_likelihood_rates_and_a_short_track(monkeypatch):
    monkeypatch.setattr(smc, "BATCH", 50)
    rates = smc._likelihood_rates(repeat=1, min_time=0.0)
    for name in ("cardboard-hand", "hand"):
        assert rates[name]["likelihoods_per_s"] > 0
        assert 0 < rates[name]["forward_kinematics_share"] < 1
    track = smc._track(DivideConquerTracker, n_frames=3)
    assert track["particles"] == 300 and math.isfinite(track["ms_per_frame_median"])
    assert track["finger_rms_deg_max"] < 8.0
