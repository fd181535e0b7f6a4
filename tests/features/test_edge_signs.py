"""Edge signs per link side learned at a known state (:mod:`digiteyes.features.edge_signs`),
on synthetic capsule images whose two sides differ (one lit, one in shade) and in the
feature tracker."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.errors import DigitEyesError
from digiteyes.features import FeatureOptions, measure_features
from digiteyes.features.edge_signs import NEAR_PX, learn_side_signs, mixed_contrast, side_offsets
from digiteyes.kinematics import forward_kinematics

RADIUS = 8.0


def _shaded_capsule(stick, camera, q, capsule_image, backdrop):
    """A capsule shaded across its width (134 on its lit side falling evenly to 110 on
    its shaded side, too gently to read as an edge) over a plain ``backdrop`` level,
    sensor noise 2; the projected axis ends (2, 2)."""
    start, end, _ = forward_kinematics(stick, q).link_segments()
    a, b = camera.project(np.stack([start[0], end[0]]))
    mask = capsule_image(a, b, RADIUS, fg=1.0, bg=0.0, noise=0.0)
    d = (b - a) / np.linalg.norm(b - a)
    rows, cols = np.indices(mask.shape)
    across = (cols - a[0]) * -d[1] + (rows - a[1]) * d[0]  # px from the axis
    hand = 122.0 - 1.5 * np.clip(across, -RADIUS, RADIUS)
    image = backdrop + mask * (hand - backdrop)
    return image + np.random.default_rng(0).normal(0.0, 2.0, image.shape), a, b


def test_a_side_darker_than_the_backdrop_gets_the_other_sign(stick, flat_camera, stick_state,
                                                               capsule_image):
    """Over a grey backdrop (120) the shaded side (110) is darker than it: the usual signs
    miss that side, the learned signs flip exactly it, and the link is then measured on
    its axis."""
    q = stick_state(-30.0, 3.0, 0.2)
    image, a, b = _shaded_capsule(stick, flat_camera, q, capsule_image, 120.0)
    kin = forward_kinematics(stick, q)
    assert mixed_contrast(image, flat_camera, stick, kin)
    usual = measure_features(image, flat_camera, stick, kin)
    assert (usual.n_edges[0] < FeatureOptions().min_edge_points).sum() == 1
    signs = learn_side_signs(image, flat_camera, stick, kin)
    default = np.tile([1.0, -1.0], (len(usual.link_ids), 1))
    assert (signs != default).sum() == 1
    learned = measure_features(image, flat_camera, stick, kin, side_signs=signs)
    assert learned.link_valid[0]
    m, rho = learned.line[0, :2], learned.line[0, 2]
    assert abs(m @ a - rho) < 0.5 and abs(m @ b - rho) < 0.5


def test_a_start_off_the_image_learns_no_sign(stick, flat_camera, stick_state,
                                              capsule_image):
    """The same shaded capsule over the grey backdrop, the start 4 mm (4 px) to one
    side of it: the flipped measurement finds edges, but not where the start puts the
    sides, so no sign is learned; at the true start the kept side lies on its predicted
    silhouette (within a pixel) and the flipped one too."""
    q = stick_state(-30.0, 3.0, 0.2)
    image, _, _ = _shaded_capsule(stick, flat_camera, q, capsule_image, 120.0)
    kin = forward_kinematics(stick, q)
    usual = measure_features(image, flat_camera, stick, kin)
    kept = usual.n_edges[0] >= FeatureOptions().min_edge_points
    assert side_offsets(usual)[0][kept].max() < 1.0
    default = np.tile([1.0, -1.0], (len(usual.link_ids), 1))
    flipped = measure_features(image, flat_camera, stick, kin, side_signs=-default)
    assert side_offsets(flipped)[0][~kept].max() < 1.0
    off = stick_state(-30.0, 7.0, 0.2)
    kin_off = forward_kinematics(stick, off)
    assert np.array_equal(learn_side_signs(image, flat_camera, stick, kin_off), default)
    far = measure_features(image, flat_camera, stick, kin_off, side_signs=-default)
    found = far.n_edges[0] >= FeatureOptions().min_edge_points
    assert found.any() and side_offsets(far)[0][found].min() > NEAR_PX


def test_black_cloth_keeps_the_usual_signs(stick, flat_camera, stick_state, capsule_image):
    """The same capsule over black cloth (20): both sides brighter than the backdrop, the
    camera is not mixed, and the signs are the usual ones (the measurement unchanged)."""
    q = stick_state(-30.0, 3.0, 0.2)
    image, _, _ = _shaded_capsule(stick, flat_camera, q, capsule_image, 20.0)
    kin = forward_kinematics(stick, q)
    assert not mixed_contrast(image, flat_camera, stick, kin)
    signs = learn_side_signs(image, flat_camera, stick, kin)
    assert np.array_equal(signs, np.tile([1.0, -1.0], (len(signs), 1)))
    with pytest.raises(DigitEyesError, match="side_signs"):
        measure_features(image, flat_camera, stick, kin, side_signs=np.ones((3, 2)))


def test_the_tracker_learns_the_signs_once_and_keeps_them(desk):
    """By default the feature tracker learns one (L, 2) array per camera on its first
    frame (on the flesh desk render over black cloth: the usual signs) and keeps it
    through a restart; asked not to, it learns none."""
    from digiteyes.trackers import FeatureTracker, FeatureTrackerOptions

    model, rig, q, _, image, _ = desk
    tracker = FeatureTracker(model, rig)
    tracker.reset(q)
    tracker.step([image])
    signs = tracker.side_signs
    assert len(signs) == 1 and signs[0].shape[1] == 2
    assert np.array_equal(signs[0], np.tile([1.0, -1.0], (len(signs[0]), 1)))
    tracker.restart(q)
    assert tracker.side_signs is signs
    off = FeatureTracker(model, rig, options=FeatureTrackerOptions(learn_edge_signs=False))
    off.reset(q)
    off.step([image])
    assert off.side_signs is None
