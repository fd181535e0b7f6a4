"""Smoke run of ``digiteyes bench accuracy --quick``: every row of the table is there,
with finite figures and the loss flag's scores."""

import json
import math

import numpy as np
import pytest

from digiteyes.benchmarks import accuracy
from digiteyes.errors import DigitEyesError


def test_quick_accuracy_bench_writes_every_row(tmp_path):
    path = tmp_path / "accuracy.json"
    result = accuracy.run(json_path=str(path), quick=True, trackers=["features"])
    data = json.loads(path.read_text())
    assert data["settings"]["frames"] == {"features": accuracy.QUICK_FRAMES}
    assert data["settings"]["workers"] == 1
    rows = data["rows"]
    combos = {(r["tracker"], r["appearance"], r["setup"], r["hand"]) for r in rows}
    assert combos == {("features", a, s, h) for a in accuracy.APPEARANCES
                      for s in accuracy.SETUPS for h in accuracy.HANDS}
    for row in rows:
        for key in ("fingertip_err_mm_mean", "fingertip_err_mm_median",
                    "joint_angle_err_deg_rms", "palm_pos_err_mm_mean", "palm_rot_err_deg_mean"):
            assert math.isfinite(row[key]), (key, row)
        assert 0 <= row["track_life_frames"] <= row["frames"] == accuracy.QUICK_FRAMES
        # the worst frame's mean fingertip error bounds the run's mean from above
        assert row["worst_frame_tip_err_mm"] >= row["fingertip_err_mm_mean"] - 1e-9
        assert row["frames_tip_err_above_30mm"] <= row["truly_lost_frames"]
        assert (row["frames_tip_err_above_30mm"] > 0) == (row["worst_frame_tip_err_mm"] > 30)
        flag = row["flag"]
        assert flag["true_positive"] + flag["false_negative"] == row["truly_lost_frames"]
        for key in ("precision", "recall"):
            assert flag[key] is None or 0.0 <= flag[key] <= 1.0
        fingers = row["finger_flag"]  # the feature tracker judges the five digits
        assert fingers["judged"] == 5 * row["frames"]
    totals = data["flag_totals"]["features"]
    assert set(totals) == set(accuracy.APPEARANCES)
    assert sum(t["frames"] for t in totals.values()) == len(rows) * accuracy.QUICK_FRAMES
    assert set(data["finger_flag_totals"]["features"]) == set(accuracy.APPEARANCES)
    # one tracker: the totals over all trackers are its totals
    assert data["flag_totals_all"] == totals
    assert result["rows"] == rows


def test_another_seed_tracks_another_motion(tmp_path):
    """``seed`` draws another motion (the scenario's states differ, the rows' figures with
    them) and is recorded in the JSON; the default is the committed table's seed."""
    assert not np.allclose(accuracy.scenario_for("desk", "exact", 3).states,
                           accuracy.scenario_for("desk", "exact", 3, seed=1).states)
    rows = {seed: accuracy.source_rows("model", "exact", "whole-hand", {"features": 3},
                                       seed=seed) for seed in (accuracy.SEED, 1)}
    assert [r["fingertip_err_mm_mean"] for r in rows[accuracy.SEED]] != \
        [r["fingertip_err_mm_mean"] for r in rows[1]]
    path = tmp_path / "accuracy.json"
    accuracy.run(json_path=str(path), quick=True, trackers=["features"], seed=1)
    assert json.loads(path.read_text())["settings"]["seed"] == 1


def test_frames_per_tracker():
    full = accuracy.frames_per_tracker(["features", "divide-conquer", "condensation",
                                        "random-search"])
    assert full["features"] == accuracy.FRAMES
    assert full["condensation"] == accuracy.TRACKER_FRAMES["condensation"] < accuracy.FRAMES
    assert full["divide-conquer"] == accuracy.TRACKER_FRAMES["divide-conquer"]
    assert set(accuracy.frames_per_tracker(["features", "condensation"], quick=True)
               .values()) == {accuracy.QUICK_FRAMES}
    assert accuracy.frames_per_tracker(["condensation"], frames=7) == {"condensation": 7}
    with pytest.raises(DigitEyesError, match="at least 2 frames"):
        accuracy.frames_per_tracker(["features"], frames=1)


def test_each_tracker_tracks_its_own_frames_of_one_render():
    rows = accuracy.source_rows("model", "exact", "webcam", {"features": 3, "templates": 2})
    assert [(r["tracker"], r["setup"], r["frames"]) for r in rows] == [
        ("features", "webcam 1cam", 3), ("templates", "webcam 1cam", 2)]
    for row in rows:
        assert row["flag"]["lost_frames"] == row["truly_lost_frames"]
        assert row["finger_flag"]["judged"] == 5 * row["frames"]


def test_a_tracker_whose_extra_is_absent_is_left_out(monkeypatch, capsys):
    """Without MediaPipe the default table runs every tracker but ``features+keypoints``,
    and says why."""
    from digiteyes.trackers import anchored_features

    monkeypatch.setattr(anchored_features, "mediapipe_available", lambda: False)
    names = accuracy.available_trackers()
    assert "features+keypoints" not in names and names[0] == "features"
    assert "keypoints" in names  # its detector falls back to the classic one
    assert "tracker features+keypoints left out" in capsys.readouterr().out
