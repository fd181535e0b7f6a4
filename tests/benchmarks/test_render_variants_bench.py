"""``digiteyes bench render-variants`` on one setup: each variant really changes the
render, every row is scored against the truth, the totals sum the rows, and the JSON it
writes is read back."""

from __future__ import annotations

import json

import numpy as np
import pytest

from digiteyes.benchmarks import accuracy, render_variants
from digiteyes.benchmarks.tracker import render_sequence
from digiteyes.cli import main

VARIANTS = {"baseline": {}, "sensor noise 8": {"noise_sigma": 8.0}}


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(accuracy, "SETUPS", {"webcam 1cam": ("webcam", None)})
        patch.setattr(render_variants, "SETUPS", accuracy.SETUPS)
        patch.setattr(render_variants, "TRACKERS", ("features",))
        patch.setattr(render_variants, "DETECTOR_TRACKERS", ())
        patch.setattr(render_variants, "VARIANTS", VARIANTS)
        patch.setattr(render_variants, "QUICK_FRAMES", 8)
        path = tmp_path_factory.mktemp("bench") / "variants.json"
        assert main(["bench", "render-variants", "--quick", "--json", str(path)]) == 0
        return json.loads(path.read_text(encoding="utf-8"))


def test_a_variant_changes_the_render():
    """The noisy variant's backdrop (far corner of the first frame) spreads four times
    as much as the baseline's: the option reaches the renderer."""
    scenario = accuracy.scenario_for("webcam", "exact", 1)
    spreads = [float(np.std(render_sequence(scenario, appearance="flesh", render=render)
                            .images[0][0][:40, :40].astype(float)))
               for render in VARIANTS.values()]
    assert spreads[1] > 3 * spreads[0]


def test_rows_are_scored_and_totals_sum_them(result):
    rows = result["rows"]
    assert {(r["variant"], r["appearance"]) for r in rows} == {
        (v, a) for v in VARIANTS for a in accuracy.APPEARANCES}
    for row in rows:
        flag = row["flag"]
        assert row["frames"] == 8
        assert flag["true_positive"] + flag["false_negative"] == row["truly_lost_frames"]
        assert flag["true_positive"] + flag["false_positive"] == row["lost_frames"]
        total = result["totals"][f"{row['variant']} | features | {row['appearance']}"]
        assert total["fingertip_err_mm_mean"] == pytest.approx(row["fingertip_err_mm_mean"])
        assert total["flag"]["true_positive"] == flag["true_positive"]
    assert result["settings"]["variants"] == VARIANTS and result["machine"]["cpu"]


def test_the_detector_tracker_joins_where_mediapipe_is_installed(monkeypatch):
    """``features+keypoints`` (what ``track --tracker auto`` runs on a dataset) is measured
    beside the seeds' trackers only where the MediaPipe extra is installed."""
    monkeypatch.setattr(render_variants, "mediapipe_available", lambda: False)
    assert render_variants.trackers() == render_variants.TRACKERS
    monkeypatch.setattr(render_variants, "mediapipe_available", lambda: True)
    assert render_variants.trackers() == (*render_variants.TRACKERS, "features+keypoints")
