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


def test_rows_average_over_noise_seeds():
    """Each seed draws other sensor noise (so the tracks differ a little); a row holds
    the mean of the seeds' figures and every seed's figure beside it."""
    from digiteyes.benchmarks.templates import seed_mean

    runs = [track_scenario("two-finger-occlusion", 1, 4, LayeredTemplateOptions(),
                           "templates", "model", seed) for seed in (0, 1)]
    assert [r["seed"] for r in runs] == [0, 1]
    assert runs[0]["mean_tip_error_mm"] != runs[1]["mean_tip_error_mm"]
    assert all(r["truly_lost_frames"] == 0 for r in runs)  # the first frames are easy
    row = seed_mean(runs)
    assert row["seeds"] == [0, 1]
    assert row["per_seed"]["mean_tip_error_mm"] == [r["mean_tip_error_mm"] for r in runs]
    assert row["mean_tip_error_mm"] == pytest.approx(
        np.mean([r["mean_tip_error_mm"] for r in runs]))
    assert row["tip_error_per_frame_mm"] == [r["tip_error_per_frame_mm"] for r in runs]
    assert set(row["ms_per_iteration"]) == set(runs[0]["ms_per_iteration"])


def test_a_row_names_the_options_it_runs_with():
    """The background template and the finger search are opt-in; a row run with either
    says so in its label, and the background it ran with is in the row; so does a row
    whose refresh gate or order at the joints is not its rig's default."""
    from dataclasses import replace

    from digiteyes.benchmarks.templates import run_label

    options = LayeredTemplateOptions()
    row = track_scenario("two-finger-occlusion", 1, 3, replace(options, background="filtered"),
                         "templates", "model")
    assert row["background"] == "filtered"
    assert run_label(row) == "templates +background"
    assert run_label(row | {"background": "none", "finger_search": True}) == "templates +search"
    assert run_label(row | {"background": "none"}) == "templates"
    assert row["refresh_gated"]  # one camera: gated by default
    plain = row | {"background": "none"}
    assert run_label(plain | {"refresh_gated": False}) == "templates ungated"
    assert not row["pixel_depth_at_joints"]  # one camera: the joint rule by default
    assert run_label(plain | {"pixel_depth_at_joints": True}) == "templates +pixel depth"
    two = plain | {"cameras": 2, "pixel_depth_at_joints": True, "hiding_costs": True}
    assert run_label(two | {"refresh_gated": False}) == "templates"
    assert run_label(two | {"refresh_gated": True}) == "templates +gated"
    assert run_label(two | {"refresh_gated": False, "pixel_depth_at_joints": False}) == (
        "templates joint rule")
    assert not row["hiding_costs"]  # one camera: hiding is free by default
    assert run_label(plain | {"hiding_costs": True}) == "templates +hiding cost"
    assert run_label(two | {"refresh_gated": False, "hiding_costs": False}) == (
        "templates free hiding")
    assert run_label(two | {"refresh_gated": False, "hiding_costs": True}) == "templates"


def test_the_desk_rows_compare_the_curl_search_with_the_defaults():
    """The desk section: for each appearance and hand both trackers at their defaults and
    with the curl search, each row with the worst frame, the frames above 30 mm and the
    loss flag's scores; the first frames of the desk pair are tracked closely."""
    from digiteyes.benchmarks.templates import CURL_SEARCH, desk_lines, desk_pair

    rows = desk_pair(4)
    assert len(rows) == 16
    assert {(r["appearance"], r["hand"], r["tracker"], r["setting"]) for r in rows} == {
        (a, h, t, s) for a in ("model", "flesh") for h in ("exact", "scaled")
        for t in ("templates", "templates+features") for s in ("default", "+curl search")}
    assert all(CURL_SEARCH.values())
    for r in rows:
        assert r["worst_frame_tip_err_mm"] >= r["fingertip_err_mm_mean"]
        assert r["worst_frame_tip_err_mm"] < 15.0  # before the fingers curl
        assert r["frames_tip_err_above_30mm"] == 0 and r["truly_lost_frames"] == 0
        assert set(r["flag"]) >= {"precision", "recall"}
    assert len(desk_lines(rows)) == 2 + len(rows)


def test_a_curl_search_row_says_so():
    from dataclasses import replace

    from digiteyes.benchmarks.templates import CURL_SEARCH, run_label

    row = track_scenario("two-finger-occlusion", 1, 3,
                         replace(LayeredTemplateOptions(), **CURL_SEARCH), "templates", "model")
    assert row["curl_search"] and run_label(row) == "templates +curl search"
    assert not track_scenario("two-finger-occlusion", 1, 3, LayeredTemplateOptions(),
                              "templates", "model")["curl_search"]
