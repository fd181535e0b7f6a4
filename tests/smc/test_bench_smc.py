"""``digiteyes bench smc`` pieces on a tiny run (figures finite, accuracy sane)."""

import math

import numpy as np
import pytest

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


def test_fig3_records_per_frame_errors_and_plots(monkeypatch, tmp_path):
    monkeypatch.setattr(smc, "FIG3_SCENARIOS", ("natural", "no-such-scenario"))
    monkeypatch.setattr(smc, "FIG3_RUNS", {"DivideConquerTracker": (DivideConquerTracker, None)})
    fig3 = smc._fig3(n_frames=3, seeds=(0, 1))
    assert "skipped" in fig3["no-such-scenario"]
    record = fig3["natural"]["DivideConquerTracker"]
    errors = record["finger_rms_deg_per_frame"]  # the first seed's
    assert len(errors) == 3 and max(errors) < 8.0
    seeds = record["seeds"]
    assert seeds["seeds"] == [0, 1] and seeds["finger_rms_deg_mean"][0] == pytest.approx(
        record["finger_rms_deg_mean"])
    assert seeds["mean_over_seeds"] == pytest.approx(np.mean(seeds["finger_rms_deg_mean"]))
    assert seeds["max_over_seeds"] == pytest.approx(np.mean(seeds["finger_rms_deg_max"]))
    path = smc.plot_fig3(fig3, tmp_path / "fig3.png")
    assert (tmp_path / "fig3.png").stat().st_size > 10_000 and path.endswith("fig3.png")


def test_the_flesh_hand_is_tracked_through_the_same_path(monkeypatch, tmp_path):
    """Fig. 3 on the independent flesh hand: the same records, finite, sane at the start;
    the plot takes one panel per appearance and scenario."""
    monkeypatch.setattr(smc, "FIG3_SCENARIOS", ("natural",))
    monkeypatch.setattr(smc, "FIG3_RUNS", {"DivideConquerTracker": (DivideConquerTracker, None)})
    flesh = smc._fig3(n_frames=3, appearance="flesh", seeds=(0,))
    errors = flesh["natural"]["DivideConquerTracker"]["finger_rms_deg_per_frame"]
    assert len(errors) == 3 and max(errors) < 8.0
    panels = {"natural, own drawing": smc._fig3(n_frames=3, seeds=(0,))["natural"],
              "natural, flesh hand": flesh["natural"]}
    smc.plot_fig3(panels, tmp_path / "fig3.png")
    assert (tmp_path / "fig3.png").stat().st_size > 10_000


def test_long_run_scores_both_variants_against_the_truth():
    """The long-run record: per appearance, the proposed tracker and Huang alone, one run
    per seed with fingertip error and loss counts, and their means."""
    out = smc._long_run(n_frames=4, seeds=(0, 1))
    assert set(out) == {"model", "flesh"}
    for variants in out.values():
        assert set(variants) == {"proposed", "huang_only"}
        for record in variants.values():
            runs = record["runs"]
            assert [r["seed"] for r in runs] == [0, 1]
            for run in runs:
                assert run["frames"] == 4
                assert 0 <= run["fingertip_mm_mean"] < 25.0 and run["truly_lost_frames"] == 0
            tips = [r["fingertip_mm_mean"] for r in runs]
            assert record["mean"]["fingertip_mm_mean"] == pytest.approx(np.mean(tips))
            assert record["range"]["fingertip_mm_mean"] == [min(tips), max(tips)]


def test_recovery_starts_far_off_and_converges_on_both_appearances():
    out = smc._recovery(n_frames=4)
    assert set(out) == {"model", "flesh"}
    for record in out.values():
        assert record["start_error_deg"] > 20.0
        assert len(record["finger_rms_deg_per_frame"]) == 4
        assert record["first_frame_below"] is not None and record["first_frame_below"] <= 3
