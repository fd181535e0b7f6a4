"""Optional check of benchmarks/real_video.py's run names (not a core test; skipped
without ``../shared/data``): ``NAME@DETECTOR`` runs that tracker with that detector, and
``NAME:N`` sets the detection check, on the first frames of the real video."""

from __future__ import annotations

from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parents[3] / "shared" / "data"

pytestmark = pytest.mark.skipif(
    not (DATA / "real_video" / "human_hand_video.mp4").is_file(),
    reason=f"real video absent ({DATA}); it lives beside the project")


def test_a_run_named_with_a_detector_uses_that_detector(benchmark_script, tmp_path):
    script = benchmark_script("real_video")
    row = script.measure(DATA, 6, "auto", "features:0@classic", tmp_path / "run")
    assert row["tracker"] == "features"
    assert row["detector"] == "ClassicDetector"
    assert row["detection_check"] is None
    assert row["frames_tracked"] == 6 and row["frames_without_state"] == 0
    assert "classic detector" in script._label(row)


def test_the_keypoint_tracker_on_the_lite_network_is_named_for_it(benchmark_script, tmp_path):
    pytest.importorskip("mediapipe")
    script = benchmark_script("real_video")
    row = script.measure(DATA, 4, "auto", "keypoints@mediapipe-lite", tmp_path / "run")
    assert row["tracker"] == "keypoints" and row["frames_tracked"] == 4
    assert script._label(row) == "keypoints, mediapipe-lite detector"
    assert script._label(row | {"run": "keypoints"}) == "keypoints"
