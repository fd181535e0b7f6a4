"""Smoke run of ``digiteyes bench accuracy --quick``: every row of the table is there,
with finite figures and the loss flag's scores."""

import json
import math

from digiteyes.benchmarks import accuracy


def test_quick_accuracy_bench_writes_every_row(tmp_path):
    path = tmp_path / "accuracy.json"
    result = accuracy.run(json_path=str(path), quick=True, trackers=["features"])
    data = json.loads(path.read_text())
    assert data["settings"]["frames"] == accuracy.QUICK_FRAMES
    rows = data["rows"]
    combos = {(r["tracker"], r["appearance"], r["setup"], r["hand"]) for r in rows}
    assert combos == {("features", a, s, h) for a in accuracy.APPEARANCES
                      for s in accuracy.SETUPS for h in accuracy.HANDS}
    for row in rows:
        for key in ("fingertip_err_mm_mean", "fingertip_err_mm_median",
                    "joint_angle_err_deg_rms", "palm_pos_err_mm_mean", "palm_rot_err_deg_mean"):
            assert math.isfinite(row[key]), (key, row)
        assert 0 <= row["track_life_frames"] <= row["frames"] == accuracy.QUICK_FRAMES
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
    assert result["rows"] == rows
