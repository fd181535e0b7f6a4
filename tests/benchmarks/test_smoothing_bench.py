"""The smoothing benchmark's measures on inputs with known answers (no tracking)."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.benchmarks import smoothing as bench
from digiteyes.kinematics import load_model


def test_lag_recovers_a_known_delay():
    t = np.arange(60, dtype=float)
    truth = np.stack([np.sin(0.2 * t), np.cos(0.13 * t), 0.01 * t ** 1.5], axis=-1)[:, None, :]
    delayed = np.stack([np.sin(0.2 * (t - 1.3)), np.cos(0.13 * (t - 1.3)),
                        0.01 * np.clip(t - 1.3, 0, None) ** 1.5], axis=-1)[:, None, :]
    lag, rms = bench.lag_frames(delayed, truth)
    assert lag == pytest.approx(1.3, abs=bench.LAG_STEP)
    assert rms < 0.01
    assert bench.lag_frames(truth, truth) == (0.0, 0.0)


def test_jitter_of_a_still_and_a_trembling_hand():
    model = load_model("hand")
    still = np.repeat(model.neutral()[None], 20, axis=0)
    assert bench.jitter(model, still) == {"keypoint_mm": 0.0, "joint_angle_deg": 0.0}
    trembling = still.copy()
    trembling[::2, 4] += 1.0  # the palm jumps 1 mm along x every other frame
    assert bench.jitter(model, trembling)["keypoint_mm"] == pytest.approx(1.0)
    assert bench.jitter(model, trembling)["joint_angle_deg"] == 0.0


def test_targets_need_both_ratio_and_lag():
    raw = {"jitter_still": {"keypoint_mm": 1.0}, "lag_frames": 0.1}

    def filtered(jitter, lag):
        return {"jitter_still": {"keypoint_mm": jitter}, "lag_frames": lag}

    assert bench._versus(raw, filtered(0.19, 1.1))["meets_targets"]
    assert not bench._versus(raw, filtered(0.21, 0.5))["meets_targets"]
    assert not bench._versus(raw, filtered(0.1, 1.2))["meets_targets"]


def _row(ratio, lag, band=10.0, peak=5.0):
    return {"jitter_ratio": ratio, "added_lag_frames": lag, "deadband_mm_s": band,
            "filtered": {"still_peak_speed_mm_s": peak}}


def test_the_tuning_rule_takes_the_steadiest_setting_within_the_lag_margin():
    rows = [_row(9.0, bench.TUNING_ADDED_LAG + 0.05), _row(6.0, bench.TUNING_ADDED_LAG),
            _row(4.0, 0.2)]
    assert bench.choose(rows) is rows[1]
    assert bench.choose(rows[:1]) is None


def test_ties_go_to_the_setting_furthest_from_both_failures():
    """Among equally steady rows: lag margins 0.6, 0.3, 0.7 and noise margins 0.5, 0.8,
    0.0 (dead band 0: no margin at all); the smaller margins are 0.5, 0.3, -inf."""
    rows = [_row(10.0, 0.4, band=10.0, peak=5.0), _row(10.0 * (1 - bench.TIE / 2), 0.7,
                                                       band=25.0, peak=5.0),
            _row(10.0, 0.3, band=0.0, peak=5.0), _row(9.0, 0.0, band=50.0, peak=1.0)]
    assert bench.choose(rows) is rows[0]
    assert bench._margin(rows[1]) == pytest.approx(0.3)


def test_the_shipped_defaults_are_in_the_grid():
    from digiteyes.filters import OneEuroOptions

    assert OneEuroOptions() in bench.grid_options()


def test_slow_motion_of_a_still_hand_has_no_error():
    model = load_model("hand")
    still = np.repeat(model.neutral()[None], 30, axis=0)
    from digiteyes.filters import OneEuroOptions

    rows = bench.slow_motion(model, still, 10.0, OneEuroOptions())
    assert [r["factor"] for r in rows] == list(bench.SLOW_FACTORS)
    assert all(r["error_mm_max"] < 1e-9 and r["speed_mm_s_median"] < 1e-9 for r in rows)
