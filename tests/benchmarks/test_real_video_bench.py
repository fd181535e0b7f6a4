"""Optional check of benchmarks/real_video.py's run names (not a core test; skipped
without ``../shared/data``): ``NAME@DETECTOR`` runs that tracker with that detector, and
``NAME:N`` sets the detection check, on the first frames of the real video."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[2] / "benchmarks"
DATA = BENCHMARKS.parents[1] / "shared" / "data"

pytestmark = pytest.mark.skipif(
    not (DATA / "real_video" / "human_hand_video.mp4").is_file(),
    reason=f"real video absent ({DATA}); it lives beside the project")


def _load_script():
    sys.path.insert(0, str(BENCHMARKS))
    spec = importlib.util.spec_from_file_location("real_video_script",
                                                  BENCHMARKS / "real_video.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_a_run_named_with_a_detector_uses_that_detector(tmp_path):
    script = _load_script()
    row = script.measure(DATA, 6, "auto", "features:0@classic", tmp_path / "run")
    assert row["tracker"] == "features"
    assert row["detector"] == "ClassicDetector"
    assert row["detection_check"] is None
    assert row["frames_tracked"] == 6 and row["frames_without_state"] == 0
    assert "classic detector" in script._label(row)
