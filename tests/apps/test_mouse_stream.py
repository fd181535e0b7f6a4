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


def test_smoothed_stream_is_the_one_euro_filter_of_the_tracked_states():
    """``smoothed``: states equal the batch One Euro filter of the raw stream (restarting
    after the lost frame), poles and buttons follow the filtered state, frames and
    overlays are kept."""
    from digiteyes.apps.mouse3d import pole_from_state
    from digiteyes.apps.mouse_stream import MouseFrame, smoothed
    from digiteyes.filters import OneEuroOptions, one_euro_filter

    scenario, _ = render_scenario_frames("mouse", n_frames=30)
    model, states = scenario.model, scenario.states[:30]
    rng = np.random.default_rng(1)
    noisy = states.copy()
    noisy[:, 7:] += rng.normal(0.0, 0.02, noisy[:, 7:].shape)
    lost = np.zeros(30, dtype=bool)
    lost[12] = True
    raw = [MouseFrame(i, q, pole_from_state(model, q), {}, bool(lost[i]), 0.0, 0.0, b"jpg")
           for i, q in enumerate(noisy)]
    out = list(smoothed(raw, model, 30.0, OneEuroOptions()))
    reset = np.concatenate([[False], lost[:-1]])
    expected = one_euro_filter(model, noisy, 30.0, OneEuroOptions(), reset=reset)
    np.testing.assert_allclose([f.state for f in out], expected, atol=1e-12)
    np.testing.assert_allclose(out[20].pole, pole_from_state(model, expected[20]))
    assert [f.index for f in out] == list(range(30))
    assert all(f.overlay_jpeg == b"jpg" for f in out) and out[12].lost
    assert np.abs(np.array([f.state for f in out]) - noisy).max() > 1e-3


def test_open_mouse_stream_with_smooth_filters_the_tracked_scenario():
    """``digiteyes mouse --smooth`` on the rendered scenario: the served states are the
    filter of those served without it."""
    from digiteyes.apps.mouse_stream import open_mouse_stream
    from digiteyes.filters import OneEuroOptions, one_euro_filter

    plain = open_mouse_stream(None, frames=6, fps=200.0, overlay=False)
    raw = np.array([f.state for f in plain.frames])
    steady = open_mouse_stream(None, frames=6, fps=200.0, overlay=False,
                               smooth=OneEuroOptions())
    got = np.array([f.state for f in steady.frames])
    np.testing.assert_allclose(got, one_euro_filter(plain.model, raw, 200.0), atol=1e-9)


def test_a_replay_plays_at_the_rate_its_run_recorded(tmp_path):
    """``--replay RUN`` without ``--fps`` takes RUN/summary.json's frame rate, else 10."""
    import json

    from digiteyes.apps.mouse_stream import open_mouse_stream
    from digiteyes.io import StateLogWriter
    from digiteyes.kinematics import load_model

    model = load_model("mouse-hand")
    with StateLogWriter(tmp_path / "states.csv", model) as log:
        for i in range(3):
            log.append(i, model.neutral(), time_s=0.0, lost=False, residual_rms_px=0.0,
                       iterations=1)
    assert open_mouse_stream(replay=str(tmp_path)).fps == 10.0
    (tmp_path / "summary.json").write_text(json.dumps({"fps": 25.0}))
    assert open_mouse_stream(replay=str(tmp_path)).fps == 25.0
    assert open_mouse_stream(replay=str(tmp_path), fps=5.0).fps == 5.0
