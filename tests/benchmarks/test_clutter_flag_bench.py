"""``digiteyes bench clutter-flag`` on one setup: the same tracks both ways, the colour model
accepted, its flags scored against the truth, and the JSON it writes read back."""

from __future__ import annotations

import json

import pytest

from digiteyes.benchmarks import accuracy, clutter_flag
from digiteyes.cli import main


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(accuracy, "SETUPS", {"webcam 1cam": ("webcam", None)})
        patch.setattr(clutter_flag, "SETUPS", accuracy.SETUPS)
        patch.setattr(clutter_flag, "TRACKERS", ("features",))
        patch.setattr(clutter_flag, "APPEARANCES", ("flesh",))
        patch.setattr(clutter_flag, "QUICK_FRAMES", 12)
        path = tmp_path_factory.mktemp("bench") / "clutter.json"
        assert main(["bench", "clutter-flag", "--quick", "--json", str(path)]) == 0
        return json.loads(path.read_text(encoding="utf-8"))


def test_rows_differ_only_in_the_flag(result):
    off, on = result["rows"]
    assert (off["colour_model"], on["colour_model"]) == (False, True)
    assert off["fingertip_err_mm_mean"] == on["fingertip_err_mm_mean"]
    assert off["truly_lost_frames"] == on["truly_lost_frames"] and off["frames"] == 12
    camera = on["cameras"][0]
    assert not camera["grey_threshold"] and camera["colour_model"]["hand_recall"] >= 0.9
    for row in (off, on):
        flag = row["flag"]
        assert flag["true_positive"] + flag["false_negative"] == row["truly_lost_frames"]
        assert flag["true_positive"] + flag["false_positive"] == row["lost_frames"]


def test_totals_sum_the_rows(result):
    for row in result["rows"]:
        key = f"features flesh colour {'on' if row['colour_model'] else 'off'}"
        total = result["totals"][key]
        assert total["true_positive"] == row["flag"]["true_positive"]
        assert total["false_negative"] == row["flag"]["false_negative"]
    assert result["machine"]["cpu"]
