"""The feature tracker measures the hand's size on the first frame (start_size)."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.camera import Rig
from digiteyes.detect.hand_size import model_hand_length
from digiteyes.features import FeatureOptions
from digiteyes.features.selection import feature_names
from digiteyes.features.slices import prepare_image
from digiteyes.kinematics import forward_kinematics, load_model
from digiteyes.kinematics.scaling import model_of_size
from digiteyes.synth import RenderOptions, render_views
from digiteyes.trackers import FeatureTracker, FeatureTrackerOptions, feature_size
from digiteyes.trackers.divide_conquer import DivideConquerOptions, DivideConquerTracker
from digiteyes.trackers.feature_size import DEAD_BAND, MIN_GAIN, START_SCALES, start_size
from digiteyes.trackers.layered_templates import LayeredTemplateOptions, LayeredTemplateTracker

HAND = load_model("hand")




def render(size: float, rig: Rig, states: np.ndarray) -> list[list[np.ndarray]]:
    """The frames of a hand ``size`` times the model's size (noise 2 grey levels)."""
    hand = model_of_size(HAND, size)
    options = RenderOptions(noise_sigma=2.0)
    return [[view.image for view in render_views(hand, q, rig, options, rng=k)]
            for k, q in enumerate(states)]


def prepared(images: list[np.ndarray]) -> list[np.ndarray]:
    return [prepare_image(image).astype(np.float32) for image in images]


@pytest.mark.parametrize("size", [0.9, 1.0, 1.1])
@pytest.mark.parametrize("cameras", [(0, 1), (0,)])
def test_the_size_of_the_first_frame_is_found(rig, true_states, size, cameras):
    sub = Rig(tuple(rig[c] for c in cameras))
    images = [render_views(model_of_size(HAND, size), true_states[0], sub,
                           RenderOptions(noise_sigma=2.0), rng=0)[k].image
              for k in range(len(sub))]
    found = FeatureTracker(HAND, sub).start_size_at(prepared(images), true_states[0])
    assert found == pytest.approx(size, abs=0.021)


def test_a_size_must_beat_the_model_files_clearly(monkeypatch):
    one = int(np.argmin(np.abs(START_SCALES - 1.0)))
    costs = np.full(len(START_SCALES), 100.0)
    costs[2] = 100.0 * (1.0 - MIN_GAIN) + 1.0  # best, but not by MIN_GAIN
    monkeypatch.setattr(feature_size, "start_size_costs", lambda *a, **k: costs.copy())
    args = (HAND, None, 10, None, 5.0)
    assert costs[one] == 100.0 and start_size(*args) == 1.0
    costs[2] = 100.0 * (1.0 - MIN_GAIN) - 1.0
    assert start_size(*args) == START_SCALES[2]  # neighbours equal: the grid point
    costs[2], costs[one + 1] = 100.0, 10.0  # far better, but within the dead band
    assert abs(START_SCALES[one + 1] - 1.0) <= DEAD_BAND and start_size(*args) == 1.0


def test_the_cost_counts_features_not_found():
    """A size whose features miss their windows does not look cheap: each missing one
    costs a residual of INVALID_RESIDUAL_PX (no robust loss: r^2 / 2)."""
    def evaluate(sized):
        return np.ones(4), 10 if sized.links[1].length == HAND.links[1].length else 6

    costs = feature_size.start_size_costs(HAND, evaluate, 10, None, 5.0,
                                          scales=np.array([1.0, 0.9]))
    expected_missing = 4 * 0.5 * feature_size.INVALID_RESIDUAL_PX ** 2
    np.testing.assert_allclose(costs, [2.0, 2.0 + expected_missing])


def tip_errors(results, true_states, size: float) -> np.ndarray:
    """Mean fingertip error (mm) per frame of ``results`` against the hand of ``size``."""
    truth = forward_kinematics(model_of_size(HAND, size), true_states).tip_centres()[0]
    est = np.array([forward_kinematics(model_of_size(HAND, r.hand_scale), r.state)
                    .tip_centres()[0] for r in results])
    return np.linalg.norm(est - truth, axis=-1).mean(axis=1)


@pytest.mark.parametrize("cls, options", [(FeatureTracker, FeatureTrackerOptions),
                                          (LayeredTemplateTracker, LayeredTemplateOptions)])
def test_tracks_a_smaller_hand_at_its_size(rig, true_states, cls, options):
    frames = render(0.9, rig, true_states)
    tracker = cls(HAND, rig)
    tracker.reset(true_states[0])
    results = [tracker.step(f) for f in frames]
    assert tracker.scale == pytest.approx(0.9, abs=0.021)
    assert all(r.hand_scale == tracker.scale for r in results)
    sized = tip_errors(results, true_states, 0.9)
    fixed = cls(HAND, rig, options(start_size=False))
    assert fixed.scale is None
    fixed.reset(true_states[0])
    unsized = tip_errors([fixed.step(f) for f in frames], true_states, 0.9)
    assert sized.mean() < 4.0 and unsized.mean() > 3.0 * sized.mean(), (sized, unsized)
    assert len(results) == len(true_states)
    tracker.reset(true_states[0])  # a new track: the size is unknown again
    assert tracker.scale == 1.0 and tracker.model is HAND


def test_restart_keeps_the_size_and_reset_forgets_it(rig, true_states):
    frames = render(0.9, rig, true_states[:2])
    tracker = FeatureTracker(HAND, rig)
    tracker.reset(true_states[0])
    tracker.step(frames[0])
    scale = tracker.scale
    assert scale == pytest.approx(0.9, abs=0.021)
    tracker.restart(true_states[1])
    assert tracker.scale == scale and tracker.step(frames[1]).hand_scale == scale
    assert model_hand_length(tracker.model) == pytest.approx(scale * model_hand_length(HAND))
    tracker.reset(true_states[0])
    assert tracker.scale == 1.0 and tracker.model is HAND


def test_divide_and_conquer_tracks_a_smaller_hand_at_its_size(rig, true_states):
    """Huang et al.'s tracker (one camera, the particle filter seeded) measures the size
    too, and its fingertips follow the smaller hand closer than at the model's size: the
    ratio of the mean fingertip errors below 1 on each of three tracker seeds and below
    0.9 at their median (one seed is one draw of the particles; 0.56, 0.83 and 0.92 on the
    4 Dec Intel VM since the first frame's spread test holds this start's spread, which
    helps the model-size run more; 0.58-0.84 before)."""
    one = Rig((rig[0],))
    frames = render(0.9, one, true_states[:6])
    ratios = []
    for seed in (0, 1, 2):
        errors = {}
        for sizing in (True, False):
            tracker = DivideConquerTracker(HAND, one, DivideConquerOptions(start_size=sizing,
                                                                           seed=seed))
            tracker.reset(true_states[0])
            results = [tracker.step(f) for f in frames]
            if sizing:
                assert tracker.scale == pytest.approx(0.9, abs=0.021)
                assert all(r.hand_scale == tracker.scale for r in results)
            else:
                assert tracker.scale is None and all(r.hand_scale == 1.0 for r in results)
            errors[sizing] = tip_errors(results, true_states[:6], 0.9).mean()
        ratios.append(errors[True] / errors[False])
    assert max(ratios) < 1.0 and np.median(ratios) < 0.9, np.round(ratios, 2)


@pytest.mark.parametrize("cameras", [(0,), (0, 1)])
def test_a_start_off_to_the_side_keeps_the_models_size(rig, true_states, cameras):
    """A hand of the model's size started 6 mm off along the table: at the start some
    other size fits the features by chance; re-fitting the palm's position does not
    confirm it, so the model's size stays."""
    sub = Rig(tuple(rig[c] for c in cameras))
    images = [v.image for v in render_views(HAND, true_states[0], sub,
                                            RenderOptions(noise_sigma=2.0), rng=0)]
    off = true_states[0].copy()
    off[4] -= 6.0
    links, tips = feature_names(HAND)
    at_start = start_size(HAND, feature_size.feature_evaluation(
        sub, prepared(images), off, FeatureOptions(), links, tips),
        (len(links) + len(tips)) * len(sub), None, 5.0)
    assert abs(at_start - 1.0) > DEAD_BAND  # the start alone is fooled
    assert feature_size.hand_size_at(HAND, sub, images, off) == 1.0


@pytest.mark.parametrize("tracker", ["features", "templates", "templates+features",
                                     "divide-conquer", "keypoints"])
def test_track_measures_the_size_only_from_a_given_start_on_a_dataset(tracker):
    """``digiteyes track`` leaves ``start_size`` on for a dataset's own start, and turns
    it off for footage and for an automatic start (the keypoint tracker, which holds the
    palm where its fit put it, only for footage); ``--option start_size=true`` wins."""
    from digiteyes.track_job import TrackJob, job_tracker_options

    def chosen(footage, auto, options=()):
        job = TrackJob(("in",), "out", "hand", options=options)
        return job_tracker_options(job, HAND, tracker, footage, auto).get("start_size", True)

    assert chosen(False, False) is True
    assert chosen(True, False) is False
    assert chosen(False, True) is (tracker == "keypoints")
    assert chosen(True, True, (("start_size", True),)) is True
