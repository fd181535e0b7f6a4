"""The on-the-fly mouse stream: the tracker is warmed up before the first frame's clock
starts, and the warm-up does not change the track."""

from __future__ import annotations

import time

import numpy as np

from digiteyes.apps.mouse_stream import render_scenario_frames, timestamped, track_frames
from digiteyes.trackers import FeatureTracker, FeatureTrackerOptions


def test_tracked_stream_matches_the_tracker_and_keeps_warm_up_out_of_the_latency():
    scenario, rendered = render_scenario_frames("mouse", n_frames=3)
    frames = list(rendered)
    options = FeatureTrackerOptions(iterations_per_frame=2)
    started = time.time()
    stamped = [(started - 60.0, images) for images in frames]  # frames "taken" a minute ago
    stream = list(track_frames(scenario.model, scenario.rig, stamped, scenario.initial_state,
                               options, overlay=False))
    tracker = FeatureTracker(scenario.model, scenario.rig, options)
    tracker.reset(scenario.initial_state)
    expected = [tracker.step(images).state for images in frames]
    np.testing.assert_allclose([f.state for f in stream], expected, rtol=0, atol=1e-12)
    assert [f.index for f in stream] == [0, 1, 2]
    # the first frame is stamped again after the warm-up step; the others keep their time
    assert stream[0].t_frame >= started
    assert [f.t_frame for f in stream[1:]] == [started - 60.0] * 2
    assert all(f.t_frame <= f.t_state for f in stream)
    assert len(list(track_frames(scenario.model, scenario.rig, timestamped([]),
                                 scenario.initial_state, options))) == 0
