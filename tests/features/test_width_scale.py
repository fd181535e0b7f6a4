"""Link widths measured on one frame: the model's own radii come back as factor 1, a hand
with thinner digits as its thinner factor, and the feature tracker keeps them across a
restart."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from digiteyes.camera import Rig
from digiteyes.features import measure_features
from digiteyes.features.width_scale import LIMITS, link_radius_scales
from digiteyes.kinematics import KinematicModel, forward_kinematics
from digiteyes.kinematics.model_file import ShapeSpec
from digiteyes.synth import RenderOptions, render_views
from digiteyes.trackers import FeatureTracker, FeatureTrackerOptions


def thinner(model: KinematicModel, factor: float) -> KinematicModel:
    """``model`` with every cylinder link's radius times ``factor`` (tips and palm kept)."""
    frames = [dataclasses.replace(row, shape=ShapeSpec("cyl", (factor * row.shape.params[0],)))
              if row.shape is not None and row.shape.kind == "cyl" else row
              for row in model.spec.frames]
    return KinematicModel(dataclasses.replace(model.spec, frames=tuple(frames)))


def scales_on(scene, truth: KinematicModel) -> tuple[np.ndarray, np.ndarray]:
    """The factors measured on an evenly lit image of ``truth`` at the scene's state."""
    model, q, camera = scene
    image = render_views(truth, q, [camera], RenderOptions(noise_sigma=2.0, supersample=3,
                                                            ambient=1.0), rng=0)[0].image
    kin = forward_kinematics(model, q)
    meas = measure_features(image, camera, model, kin)
    cylinders = np.array([link.kind == "link" for link in model.links])
    return link_radius_scales([meas], [camera], kin), cylinders


def test_the_models_own_widths_give_factor_one(scene):
    scales, cylinders = scales_on(scene, scene[0])
    assert np.all(scales[~cylinders] == 1.0)
    assert np.abs(scales[cylinders] - 1.0).max() < 0.04


@pytest.mark.parametrize("factor", [0.8, 1.2])
def test_a_hand_with_other_widths_gives_their_factor(scene, factor):
    scales, cylinders = scales_on(scene, thinner(scene[0], factor))
    assert np.median(scales[cylinders]) == pytest.approx(factor, abs=0.03)
    assert np.abs(scales[cylinders] - factor).max() < 0.08
    assert LIMITS[0] <= scales.min() and scales.max() <= LIMITS[1]


def test_the_tracker_fits_the_widths_once_and_keeps_them_on_restart(scene):
    """A shaded hand with links 0.9 times as wide, tracked from its true state: the fitted
    factors move most of the way (the shading model, fitted on the first frame with the
    model's wider links, takes back a little), the first frame's depth error shrinks, and
    a restart keeps the factors while a reset forgets them."""
    model, q, camera = scene
    image = render_views(thinner(model, 0.9), q, [camera], RenderOptions(noise_sigma=2.0),
                         rng=0)[0].image
    cylinders = np.array([link.kind == "link" for link in model.links])
    depth_error = {}
    for fit in (True, False):
        tracker = FeatureTracker(model, Rig((camera,)), FeatureTrackerOptions(fit_widths=fit))
        tracker.reset(q)
        result = tracker.step([image])
        palm, true = (camera.to_camera(forward_kinematics(model, state).T_world_shape[0, 0, :3, 3])
                      for state in (result.state, q))
        depth_error[fit] = abs(float(palm[2] - true[2]))
        if fit:
            fitted = tracker.radius_scale.copy()
            assert 0.88 < np.median(fitted[cylinders]) < 0.95
            tracker.restart(q)
            tracker.step([image])
            assert np.array_equal(tracker.radius_scale, fitted)
            tracker.reset(q)
            assert tracker.radius_scale is None
        else:
            assert tracker.radius_scale is None
    assert depth_error[True] < 0.5 * depth_error[False], depth_error


def test_a_start_that_does_not_fit_the_image_keeps_the_models_radii(scene):
    """A start 25 mm off across the view: no link lies where it says, the track stays
    off the hand (lost), so no factors on any frame."""
    model, q, camera = scene
    image = render_views(thinner(model, 0.9), q, [camera], RenderOptions(noise_sigma=2.0),
                         rng=0)[0].image
    off = q.copy()
    off[4] += 25.0
    tracker = FeatureTracker(model, Rig((camera,)))
    tracker.reset(off)
    for _ in range(4):
        tracker.step([image])
    assert tracker.radius_scale is None


def test_a_start_near_the_hand_measures_the_widths_where_the_track_lands(scene):
    """A start 10 mm off across the view (an automatic start's size of error): the
    start does not fit the image, so no factors before the first solve; the solves
    bring the track onto the hand (within 2 mm), and the factors are measured there on
    the first frame whose solved state fits: the hand's 0.9, not the model's 1."""
    model, q, camera = scene
    image = render_views(thinner(model, 0.9), q, [camera], RenderOptions(noise_sigma=2.0),
                         rng=0)[0].image
    cylinders = np.array([link.kind == "link" for link in model.links])
    off = q.copy()
    off[4] += 10.0
    tracker = FeatureTracker(model, Rig((camera,)))
    tracker.reset(off)
    first = tracker.step([image])
    assert not first.lost and tracker.radius_scale is None  # still 6 mm off after one solve
    for _ in range(3):
        result = tracker.step([image])
    palm, true = (forward_kinematics(model, state).T_world_shape[0, 0, :3, 3]
                  for state in (result.state, q))
    assert np.linalg.norm(palm - true) < 2.0
    assert tracker.radius_scale is not None
    assert 0.85 < np.median(tracker.radius_scale[cylinders]) < 0.95


def test_the_factors_do_not_depend_on_the_width_weight(scene):
    """The shading model's predicted bias carries the tracker's width weight on its width
    rows; the factors take it out."""
    model, q, camera = scene
    image = render_views(thinner(model, 0.85), q, [camera], RenderOptions(noise_sigma=2.0),
                         rng=0)[0].image
    scales = []
    for weight in (1.0, 3.0):
        tracker = FeatureTracker(model, Rig((camera,)), FeatureTrackerOptions(width_weight=weight))
        tracker.reset(q)
        tracker.step([image])
        scales.append(tracker.radius_scale)
    assert scales[0] is not None and np.allclose(scales[0], scales[1], atol=1e-9)
