"""The DigitEyes feature tracker on rendered two-camera sequences with known truth."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.camera import Rig
from digiteyes.errors import CameraError, StateError
from digiteyes.kinematics import forward_kinematics, load_model
from digiteyes.synth import RenderOptions, render_views
from digiteyes.trackers import (
    FeatureDetails,
    FeatureTracker,
    FeatureTrackerOptions,
    Tracker,
    thesis_whole_hand_links,
)
from digiteyes.trackers.feature_tracker import track_loss_reasons

HAND = load_model("hand")


@pytest.fixture(scope="module")
def frames(rig, true_states) -> list[list[np.ndarray]]:
    options = RenderOptions(noise_sigma=2.0)
    return [[view.image for view in render_views(HAND, q, rig, options, rng=k)]
            for k, q in enumerate(true_states)]


def track(tracker, true_states, frames):
    tracker.reset(true_states[0])
    return [tracker.step(f) for f in frames]


def errors(results, true_states):
    """Joint-angle errors (deg, frames x 21), fingertip errors (mm, frames x 5), palm
    position errors (mm, frames)."""
    est = np.array([r.state for r in results])
    joints = np.degrees(np.abs(est[:, 7:] - true_states[:, 7:]))
    tips = np.linalg.norm(forward_kinematics(HAND, est).tip_centres()[0]
                          - forward_kinematics(HAND, true_states).tip_centres()[0], axis=-1)
    palm = np.linalg.norm(est[:, 4:7] - true_states[:, 4:7], axis=-1)
    return joints, tips, palm


@pytest.mark.parametrize("form", ["tangent", "quaternion"])
def test_tracks_finger_flexion_and_palm_motion(rig, true_states, frames, form):
    results = track(FeatureTracker(HAND, rig, FeatureTrackerOptions(form=form)), true_states,
                    frames)
    joints, tips, palm = errors(results, true_states)
    assert np.sqrt(np.mean(joints**2)) < 5.0  # degrees, all 21 joints, all frames
    index = [HAND.state_index(n) - 7 for n in ("index.mcp", "index.pip")]
    assert joints[:, index].max() < 10.0
    assert np.sqrt(np.mean(tips**2)) < 4.0  # mm
    assert tips.max() < 10.0
    assert palm.max() < 5.0
    assert not any(r.lost for r in results)
    assert max(r.residual_rms_px for r in results) < 2.0
    # the flexion really was followed: the estimate moved by most of the true motion
    mcp = HAND.state_index("index.mcp")
    moved = results[-1].state[mcp] - results[0].state[mcp]
    assert moved == pytest.approx(true_states[-1, mcp] - true_states[0, mcp], abs=np.radians(8))


def test_blank_frames_flag_loss_and_tracking_resumes(rig, true_states, frames):
    """Blank frames are lost; tracking resumes, and the flag is held for 3 frames after
    the last frame the rules call lost (:mod:`digiteyes.trackers.loss_hold`)."""
    tracker = FeatureTracker(HAND, rig, FeatureTrackerOptions(hold_lost_frames=3))
    blank = [np.zeros((480, 640), dtype=np.uint8)] * 2
    sequence = frames[:6] + [blank] * 3 + frames[9:]
    results = track(tracker, true_states, sequence)
    assert not any(r.lost for r in results[:6])
    for r in results[6:9]:
        assert r.lost and r.loss_reason == "no features measured"
        assert r.details.n_valid_links == r.details.n_valid_tips == 0
        assert np.isnan(r.residual_rms_px)
        assert r.details.summary.termination == "no residuals"
    # after the first blank frame the velocity is dropped: the estimate holds still
    np.testing.assert_array_equal(results[7].state, results[6].state)
    np.testing.assert_array_equal(results[8].state, results[7].state)
    assert results[11].lost and results[11].loss_reason.startswith("held: ")
    assert not any(r.lost for r in results[14:])
    joints, tips, _ = errors(results[12:], true_states[12:])
    assert np.sqrt(np.mean(joints**2)) < 5.0
    assert np.sqrt(np.mean(tips**2)) < 4.0 and tips.max() < 10.0


def test_shading_correction_steadies_one_camera(rig, true_states, frames):
    """With one camera the width rows set the depth; the shading correction removes their
    inward bias, so the palm and the fingers come out nearer the truth than without it."""
    mono = Rig(rig.cameras[:1])
    first = [f[:1] for f in frames]
    outcomes = {}
    for correct in (True, False):
        tracker = FeatureTracker(HAND, mono, FeatureTrackerOptions(shading_correction=correct))
        results = track(tracker, true_states, first)
        assert (len(tracker.edge_bias) == 1) == correct
        assert (tracker.shading is not None) == correct
        joints, tips, palm = errors(results, true_states)
        outcomes[correct] = np.sqrt(np.mean(joints**2)), np.mean(tips), np.mean(palm)
        assert not any(r.lost for r in results)
    assert outcomes[True][0] < 0.8 * outcomes[False][0]
    assert outcomes[True][2] < outcomes[False][2]


def test_no_shading_correction_over_clutter(rig, true_states):
    options = RenderOptions(background="clutter", noise_sigma=2.0)
    frames = [[v.image for v in render_views(HAND, q, rig, options, rng=k)]
              for k, q in enumerate(true_states[:2])]
    tracker = FeatureTracker(HAND, rig)
    track(tracker, true_states[:2], frames)
    assert tracker.shading.backdrop_texture > tracker.options.max_backdrop_texture
    assert tracker.edge_bias == []


def test_result_fields_and_timings(rig, true_states, frames):
    options = FeatureTrackerOptions(iterations_per_frame=3, links=thesis_whole_hand_links(HAND))
    tracker = FeatureTracker(HAND, rig, options)
    assert isinstance(tracker, Tracker)
    tracker.reset(true_states[0])
    first, second = tracker.step(frames[0]), tracker.step(frames[1])
    np.testing.assert_array_equal(first.predicted_state, true_states[0])
    assert (first.frame_index, second.frame_index) == (0, 1)
    for result in (first, second):
        d = result.details
        assert isinstance(d, FeatureDetails)
        assert result.iterations == d.summary.iterations == 3
        assert d.n_features == 2 * 18
        assert len(d.measurements) == len(d.residual_layouts) == 2
        assert [m.camera for m in d.measurements] == ["left", "right"]
        assert len(d.residuals) == sum(lay.n_rows for lay in d.residual_layouts)
        assert d.n_valid_links == sum(int(m.link_valid.sum()) for m in d.measurements)
        assert d.n_valid_tips == sum(int(m.tip_valid.sum()) for m in d.measurements)
        assert result.residual_rms_px == pytest.approx(np.sqrt(np.mean(d.residuals**2)))
        assert result.cost == pytest.approx(0.5 * d.residuals @ d.residuals)
        assert result.finger_lost and not any(result.finger_lost.values())
        assert set(result.timings) == {*FeatureTracker.stages, "total"}
        stages = [result.timings[k] for k in FeatureTracker.stages]
        # the finger search runs only on frames the silhouette rule calls lost
        assert result.timings["finger_search"] == 0.0 and not d.searched
        assert all(result.timings[k] > 0 for k in FeatureTracker.stages if k != "finger_search")
        assert sum(stages) <= result.timings["total"]
        names = {HAND.links[i].name for m in d.measurements for i in m.link_ids}
        assert "middle.proximal" not in names and "index.proximal" in names


def test_thesis_whole_hand_links():
    names = thesis_whole_hand_links(HAND)
    assert len(names) == 18  # 13 phalanges + 5 tips (thesis Sec. 4.3.3)
    assert "ring.proximal" not in names and "middle.proximal" not in names
    assert sum(n.endswith(".tip") for n in names) == 5


def test_track_loss_rules():
    options = FeatureTrackerOptions(max_invalid_fraction=0.5, growth_frames=3,
                                    growth_factor=2.0, growth_min_px=1.0)
    assert options.residual_limit_px == 10.0  # half the 20 px window
    assert track_loss_reasons(0.8, 30, 40, [0.7, 0.8], options) == []
    assert track_loss_reasons(np.nan, 0, 40, [], options) == ["no features measured"]
    (reason,) = track_loss_reasons(0.8, 19, 40, [], options)
    assert "invalid" in reason
    (reason,) = track_loss_reasons(10.5, 30, 40, [], options)
    assert "residual RMS 10.50 px > 10.00 px" in reason
    (reason,) = track_loss_reasons(2.5, 30, 40, [0.9, 1.2, 1.6, 2.0], options)
    assert "grew from 1.20 to 2.50" in reason
    assert track_loss_reasons(2.5, 30, 40, [1.2, 1.6, 1.5], options) == []  # not monotone
    assert track_loss_reasons(0.9, 30, 40, [0.1, 0.2, 0.4], options) == []  # under 1 px
    assert len(track_loss_reasons(11.0, 10, 40, [], options)) == 2
    # a hand that fails the width check on 45 % of the features at its true first state
    assert track_loss_reasons(0.8, 19, 40, [], options, first_invalid=0.45) == []
    assert track_loss_reasons(0.8, 10, 40, [], options, first_invalid=0.45)


def test_errors(rig, true_states, frames):
    tracker = FeatureTracker(HAND, rig)
    with pytest.raises(StateError, match="reset"):
        tracker.step(frames[0])
    with pytest.raises(StateError, match="28 numbers"):
        tracker.reset(np.zeros(5))
    tracker.reset(true_states[0])
    with pytest.raises(CameraError, match="2 camera"):
        tracker.step(frames[0][:1])
    with pytest.raises(CameraError, match="640x480"):
        tracker.step([np.zeros((240, 320), np.uint8)] * 2)
    with pytest.raises(ValueError, match=r"'index\.nail'"):
        FeatureTracker(HAND, rig, FeatureTrackerOptions(links=("index.distal", "index.nail")))
    with pytest.raises(ValueError, match="no cylinder link or tip"):
        FeatureTracker(HAND, rig, FeatureTrackerOptions(links=("palm",)))


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"iterations_per_frame": 0}, "iterations_per_frame"),
    ({"links": "index.tip"}, "links"),
    ({"axis_points": 0}, "axis_points"),
    ({"conditioning": (1.0, 10.0)}, "conditioning"),
    ({"conditioning": (1.0, -10.0, 1.0)}, "conditioning"),
    ({"damping": "dogleg"}, "damping"),
    ({"prediction": "kalman"}, "prediction"),
    ({"form": "euler"}, "form"),
    ({"robust_loss": "cauchy"}, "robust_loss"),
    ({"max_invalid_fraction": 1.5}, "max_invalid_fraction"),
    ({"max_residual_rms_px": 0.0}, "max_residual_rms_px"),
    ({"growth_frames": 0}, "growth_frames"),
    ({"features": {"window_px": 20}}, "FeatureOptions"),
    ({"shading_every": 0}, "shading_every"),
    ({"blur_sigma_px": -1.0}, "blur_sigma_px"),
    ({"max_backdrop_texture": 0.0}, "max_backdrop_texture"),
])
def test_options_are_validated(kwargs, match):
    with pytest.raises(ValueError, match=match):
        FeatureTrackerOptions(**kwargs)
