"""Feature residuals and their analytic Jacobians (thesis eq. 2.17-2.20, report eq. 2-3,
6-10) against central finite differences stepped through ``integrate``; width residuals
(docs/features.md, "Width residual"): zero at the true state, exact Jacobian, error check."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from digiteyes import load_model
from digiteyes.camera import Camera
from digiteyes.errors import StateError
from digiteyes.features import feature_residuals, project_features
from digiteyes.features.slices import cylinder_tangent_points
from digiteyes.kinematics import forward_kinematics, integrate
from digiteyes.kinematics.rotations import quaternion_from_rotvec

FRACTIONS = np.array([0.3, 0.5, 0.7])  # slice positions of the synthetic measurements
CAMERAS = {
    "perspective": Camera.create(
        "persp", [[800.0, 0.0, 319.5], [0.0, 790.0, 239.5], [0.0, 0.0, 1.0]], 640, 480,
        Camera.look_at("x", [150.0, -450.0, 400.0], [0.0, 40.0, 0.0]).T_cam_world,
        dist=[-0.12, 0.05, 0.001, -0.002, 0.0]),
    "orthographic": Camera.look_at("ortho", [150.0, -450.0, 400.0], [0.0, 40.0, 0.0],
                                   projection="orthographic"),
    "scaled-orthographic": Camera.look_at("sortho", [150.0, -450.0, 400.0], [0.0, 40.0, 0.0],
                                          projection="scaled-orthographic"),
}


@pytest.fixture(scope="module")
def hand():
    return load_model("hand")


def random_hand_state(model, rng) -> np.ndarray:
    q = model.neutral()
    q[0:4] = quaternion_from_rotvec(rng.normal(0.0, 0.6, 3))
    q[4:7] = rng.uniform(-20.0, 20.0, 3)
    low, high = model.lower[7:], model.upper[7:]
    q[7:] = rng.uniform(low, high)
    return q


def perturbed_measurement(model, camera, q, rng):
    """Exact features of a nearby state: residuals at q are non-zero but small."""
    q_meas = integrate(model, q, rng.normal(0.0, 0.03, model.n_v))
    return project_features(camera, model, forward_kinematics(model, q_meas))


def line_and_tip_counts(model):
    """Line features (15 phalanges + 3 palm edges for the hand) and tips (5)."""
    kinds = [link.kind for link in model.links]
    return kinds.count("link") + kinds.count("edge"), kinds.count("tip")


def residual(meas, camera, model, q):
    return feature_residuals(meas, camera, forward_kinematics(model, q), jacobian=False)[0]


@pytest.mark.parametrize("name", list(CAMERAS))
def test_tangent_jacobian_matches_finite_differences(hand, name):
    camera = CAMERAS[name]
    rng = np.random.default_rng(10)
    for _ in range(3):
        q = random_hand_state(hand, rng)
        meas = perturbed_measurement(hand, camera, q, rng)
        n_lines, n_tips = line_and_tip_counts(hand)
        assert meas.n_valid == n_lines + n_tips
        r, J, _layout = feature_residuals(meas, camera, forward_kinematics(hand, q))
        n_rows = 2 * n_lines + 2 * n_tips
        assert r.shape == (n_rows,) and J.shape == (n_rows, hand.n_v)
        assert np.abs(r).max() > 0.5
        h = 1e-6
        J_fd = np.empty_like(J)
        for i in range(hand.n_v):
            step = np.zeros(hand.n_v)
            step[i] = h
            J_fd[:, i] = (residual(meas, camera, hand, integrate(hand, q, step))
                          - residual(meas, camera, hand, integrate(hand, q, -step))) / (2 * h)
        assert np.linalg.norm(J - J_fd) / np.linalg.norm(J) < 1e-6


def test_quaternion_jacobian_matches_finite_differences(hand):
    camera = CAMERAS["perspective"]
    rng = np.random.default_rng(11)
    q = random_hand_state(hand, rng)
    q[0:4] *= 1.3  # forward kinematics normalises: derivatives of the normalised rotation
    meas = perturbed_measurement(hand, camera, q / np.r_[1.3 * np.ones(4), np.ones(24)], rng)
    r, J, _ = feature_residuals(meas, camera, forward_kinematics(hand, q), form="quaternion")
    assert J.shape == (len(r), hand.n_q)
    h = 1e-6
    J_fd = np.stack([(residual(meas, camera, hand, q + h * e) - residual(meas, camera, hand,
                                                                           q - h * e)) / (2 * h)
                     for e in np.eye(hand.n_q)], axis=1)
    assert np.linalg.norm(J - J_fd) / np.linalg.norm(J) < 1e-6


@pytest.mark.parametrize("name", list(CAMERAS))
def test_exact_features_give_zero_residuals(hand, name):
    camera = CAMERAS[name]
    q = random_hand_state(hand, np.random.default_rng(12))
    kin = forward_kinematics(hand, q)
    meas = project_features(camera, hand, kin)
    # Link base and end lie on the measured line even with lens distortion ...
    assert np.abs(feature_residuals(meas, camera, kin)[0]).max() < 1e-9
    # ... points in between only without it (distortion bends the projected axis).
    camera = dataclasses.replace(camera, dist=np.zeros(5))
    meas = project_features(camera, hand, kin)
    r, _J, _layout = feature_residuals(meas, camera, kin, axis_points=4)
    n_lines, n_tips = line_and_tip_counts(hand)
    assert r.shape == (n_lines * 4 + n_tips * 2,)
    assert np.abs(r).max() < 1e-9
    r_only, J_none, _ = feature_residuals(meas, camera, kin, jacobian=False, axis_points=4)
    assert J_none is None
    np.testing.assert_allclose(r_only, r)


def test_layout_and_invalid_features(hand):
    camera = CAMERAS["orthographic"]
    kin = forward_kinematics(hand, random_hand_state(hand, np.random.default_rng(13)))
    meas = project_features(camera, hand, kin)
    valid = meas.link_valid.copy()
    valid[[2, 5]] = False
    tips = meas.tip_valid.copy()
    tips[0] = False
    meas = dataclasses.replace(meas, link_valid=valid, tip_valid=tips)
    r, _J, layout = feature_residuals(meas, camera, kin, axis_points=3)
    n_lines, n_tips = line_and_tip_counts(hand)
    assert layout.n_rows == len(r) == (n_lines - 2) * 3 + (n_tips - 1) * 2
    assert layout.camera == camera.name
    links = layout.rows("link")
    assert len(links) == (n_lines - 2) * 3 and not np.isin(layout.feature[links], [2, 5]).any()
    np.testing.assert_array_equal(layout.component[links][:3], [0, 1, 2])
    tip_rows = layout.rows("tip")
    np.testing.assert_array_equal(layout.component[tip_rows][:2], [0, 1])
    assert 0 not in layout.feature[tip_rows]
    np.testing.assert_array_equal(layout.link_index[tip_rows][::2], meas.tip_ids[1:])
    np.testing.assert_allclose(layout.points_px[tip_rows][::2], meas.predicted_tip[1:])
    with pytest.raises(ValueError, match="form"):
        feature_residuals(meas, camera, kin, form="euler")
    with pytest.raises(ValueError, match="axis_points"):
        feature_residuals(meas, camera, kin, axis_points=0)
    batch = forward_kinematics(hand, np.stack([hand.neutral()] * 2))
    with pytest.raises(StateError, match="one state"):
        feature_residuals(meas, camera, batch)


def measured_sides(model, camera, q_meas, widen=1.0, tilt_deg=0.0):
    """Exact features of ``q_meas`` plus side lines through the projected contour points of
    each cylinder's middle slice, ``widen`` times as far apart and each turned outwards by
    ``tilt_deg``. Returns the measurement and the true middle-slice widths (L,), px."""
    kin = forward_kinematics(model, q_meas)
    meas = project_features(camera, model, kin)
    n_links = len(meas.link_ids)
    centres = np.empty((n_links, len(FRACTIONS), 2))
    sides = np.full((n_links, 2, 3), np.nan)
    widths = np.full(n_links, np.nan)
    for k, index in enumerate(meas.link_ids):
        link = model.links[index]
        T = kin.T_world_shape[0, link.row]
        points = T[:3, 3] + FRACTIONS[:, None] * link.length * T[:3, 0]
        centres[k] = camera.project(points)
        if link.kind != "link":
            continue
        contour = camera.project(cylinder_tangent_points(camera, points[1], T[:3, 0],
                                                         link.radius))
        n = meas.slice_normal[k]
        offsets = np.sort((contour - centres[k, 1]) @ n)
        widths[k] = offsets[1] - offsets[0]
        for side, offset in enumerate(offsets * widen):
            angle = np.radians(tilt_deg) * (1 if side else -1)
            c, s = np.cos(angle), np.sin(angle)
            normal = np.array([c * n[0] - s * n[1], s * n[0] + c * n[1]])
            sides[k, side] = [*normal, normal @ (centres[k, 1] + offset * n)]
    meas = dataclasses.replace(meas, side_lines=sides, slice_centres=centres,
                               slice_fractions=FRACTIONS)
    return meas, widths


def width_rows(model, meas, camera, q, **kw):
    r, J, layout = feature_residuals(meas, camera, forward_kinematics(model, q),
                                     width_weight=1.0, **kw)
    rows = layout.rows("width")
    return r, J, layout, rows


@pytest.mark.parametrize("name", ["perspective", "orthographic"])
def test_width_rows_vanish_at_the_true_state(hand, name):
    camera = CAMERAS[name]
    q = random_hand_state(hand, np.random.default_rng(20))
    meas, widths = measured_sides(hand, camera, q)
    r, _J, layout, rows = width_rows(hand, meas, camera, q)
    cylinders = [k for k, i in enumerate(meas.link_ids) if hand.links[i].kind == "link"]
    assert len(rows) == len(cylinders) == 15  # palm edges have no width
    np.testing.assert_array_equal(layout.feature[rows], cylinders)
    np.testing.assert_array_equal(layout.link_index[rows], meas.link_ids[cylinders])
    assert np.all(widths[cylinders] > 3.0)
    # The model's width is the extent of the projected cross-section along the slice; it
    # differs from the distance of the silhouette lines by a second-order amount.
    assert np.abs(r[rows]).max() < (0.05 if name == "perspective" else 1e-9)
    # Without a weight the rows are left out (the thesis's residuals only).
    r_plain, _, plain = feature_residuals(meas, camera, forward_kinematics(hand, q))
    assert len(plain.rows("width")) == 0 and len(r_plain) == len(r) - len(rows)


@pytest.mark.parametrize("name", ["perspective", "orthographic"])
def test_width_jacobian_matches_finite_differences(hand, name):
    camera = CAMERAS[name]
    # At the state the features were measured at (slice normals = projected axis normals),
    # which is where the tracker linearises: it measures again at every iterate.
    q = random_hand_state(hand, np.random.default_rng(21))
    meas, _ = measured_sides(hand, camera, q, widen=1.08, tilt_deg=3.0)
    r, J, _layout, rows = width_rows(hand, meas, camera, q, max_width_error=1e6)
    assert len(rows) == 15 and np.abs(r[rows]).max() > 0.3
    h = 1e-6
    J_fd = np.empty_like(J)
    for i in range(hand.n_v):
        step = np.zeros(hand.n_v)
        step[i] = h
        plus = width_rows(hand, meas, camera, integrate(hand, q, step), max_width_error=1e6)
        minus = width_rows(hand, meas, camera, integrate(hand, q, -step), max_width_error=1e6)
        J_fd[:, i] = (plus[0] - minus[0]) / (2 * h)
    # Orthographic widths do not depend on the pose (J ~ 0): compare absolutely there.
    scale = max(np.linalg.norm(J[rows]), 1.0)
    assert np.linalg.norm(J[rows] - J_fd[rows]) / scale < 1e-6
    assert np.linalg.norm(J - J_fd) / np.linalg.norm(J) < 1e-6


def test_widths_far_off_the_prediction_are_left_out(hand):
    camera = CAMERAS["perspective"]
    q = random_hand_state(hand, np.random.default_rng(23))
    meas, widths = measured_sides(hand, camera, q, widen=1.3)
    _r, _J, _layout, rows = width_rows(hand, meas, camera, q, max_width_error=0.15)
    assert len(rows) == 0
    r, _J, layout, rows = width_rows(hand, meas, camera, q, max_width_error=0.5)
    assert len(rows) == 15
    # predicted minus measured: 30 % of the true width, too narrow a prediction
    np.testing.assert_allclose(r[rows], -0.3 * widths[layout.feature[rows]], atol=0.05)
    with pytest.raises(ValueError, match="width_weight"):
        feature_residuals(meas, camera, forward_kinematics(hand, q), width_weight=-1.0)
