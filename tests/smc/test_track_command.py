"""``digiteyes track --tracker divide-conquer`` on a few frames of ``natural``, the
overlay drawer, then ``digiteyes evaluate`` on the run."""

import json

import numpy as np
import pytest

from digiteyes.cli import main
from digiteyes.io import open_sequence
from digiteyes.trackers import DivideConquerDetails, create_tracker, tracker_names
from digiteyes.viz.track_overlay import drawer_for


@pytest.fixture(scope="module")
def sequence(tmp_path_factory):
    folder = tmp_path_factory.mktemp("seq") / "natural"
    assert main(["render", "natural", "-o", str(folder), "--frames", "4"]) == 0
    return folder


def test_registered_with_their_options(sequence):
    assert {"divide-conquer", "condensation", "random-search"} <= set(tracker_names())
    seq = open_sequence(sequence)
    assert create_tracker("condensation", seq.model, seq.rig).options.n_particles == 3000
    tracker = create_tracker("random-search", seq.model, seq.rig, n_particles=40)
    assert tracker.options.sampler == "random-search" and tracker.options.n_particles == 40


def test_track_overlay_and_evaluate(sequence, tmp_path):
    out = tmp_path / "run"
    assert main(["track", str(sequence), "-o", str(out), "--tracker", "divide-conquer",
                 "--option", "n_particles=120", "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["tracker"] == "divide-conquer"
    assert summary["stages"] == ["edges", "proposal", "palm_icp", "likelihood", "digit_search",
                                 "resampling", "silhouette"]
    assert summary["lost_frames"] == 0
    assert (out / "overlay.mp4").stat().st_size > 1000
    assert main(["evaluate", str(out), str(sequence)]) == 0
    metrics = json.loads((out / "evaluation" / "metrics.json").read_text())
    assert metrics["run"]["frames"] == 4
    tips = np.array(list(metrics["per_frame"]["fingertip_error_mm_per_tip"].values()))
    assert np.nanmean(tips) < 15.0, tips


def test_overlay_draws_particles_and_best(sequence):
    seq = open_sequence(sequence)
    tracker = create_tracker("divide-conquer", seq.model, seq.rig, n_particles=60)
    tracker.reset(seq.initial_state)
    frame = seq.frame(0)
    result = tracker.step(frame)
    assert isinstance(result.details, DivideConquerDetails)
    assert result.details.sample_states.shape == (24, seq.model.n_q)
    draw = drawer_for(result.details)
    panel = draw(frame[0], 0, seq.rig[0], result, seq.model)
    plain = np.asarray(frame[0])
    assert panel.shape == (*plain.shape[:2], 3) and panel.dtype == np.uint8
    changed = np.any(panel != (plain[..., None] if plain.ndim == 2 else plain), axis=-1)
    assert changed.mean() > 0.005
