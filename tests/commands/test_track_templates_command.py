"""``digiteyes track --tracker templates`` then ``digiteyes evaluate``: the layered template
tracker end to end through the CLI on the start of ``two-finger-occlusion``, against truth."""

from __future__ import annotations

import json

import pytest

from digiteyes.cli import main

N_FRAMES = 10


@pytest.fixture(scope="module")
def occlusion(tmp_path_factory):
    """The first frames of the two-finger occlusion scenario (one camera)."""
    folder = tmp_path_factory.mktemp("seq") / "tfo"
    assert main(["render", "two-finger-occlusion", "-o", str(folder),
                 "--frames", str(N_FRAMES)]) == 0
    return folder


@pytest.mark.parametrize("tracker", ["templates", "templates+features"])
def test_track_templates_then_evaluate(occlusion, tmp_path, capsys, tracker):
    out = tmp_path / "out"
    assert main(["track", str(occlusion), "-o", str(out), "--quiet", "--tracker", tracker,
                 "--option", "iterations_per_frame=2"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["tracker"] == tracker and summary["frames"] == N_FRAMES
    assert summary["iterations"] == 2 * N_FRAMES
    assert "visibility" in summary["stages"] and "residual" in summary["stages"]
    assert summary["residual_unit"] == "grey level"   # not pixels: filtered grey levels
    assert summary["lost_frames"] == 0
    assert summary["lost_frames_per_finger"] == {"index": 0, "middle": 0}
    assert (out / "overlay.mp4").stat().st_size > 1000
    capsys.readouterr()
    assert main(["evaluate", str(out), str(occlusion)]) == 0
    printed = capsys.readouterr().out
    assert "track life" in printed
    residual = next(line for line in printed.splitlines() if "residual RMS" in line)
    assert residual.rstrip().endswith("grey level"), residual
    metrics = json.loads((out / "evaluation" / "metrics.json").read_text())
    assert metrics["run"]["residual_unit"] == "grey level"
    assert metrics["model"] == "two-finger"
    assert metrics["fingertip_error_mm"]["count"] == 2 * N_FRAMES
    assert metrics["fingertip_error_mm"]["mean"] < 1.5
    assert metrics["fingertip_error_mm"]["max"] < 4.0


def test_unknown_template_option_is_one_line(occlusion, tmp_path, capsys):
    assert main(["track", str(occlusion), "-o", str(tmp_path / "o"), "--quiet",
                 "--tracker", "templates", "--option", "window=3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("digiteyes: error:") and "window" in err[0]
