"""Link and tip measurement on synthetic capsule images with known geometry.

The conftest camera is orthographic with 1 px per mm, so the model's projected axis,
radius and tip are known exactly in pixels, and ``capsule_image`` draws the silhouette by
8 x 8 supersampling (exact to about 1/64 px)."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.errors import CameraError, StateError
from digiteyes.features import FeatureOptions, measure_features
from digiteyes.kinematics import forward_kinematics

RADIUS = 8.0


def truth(stick, camera, q):
    """Projected axis ends (2, 2) of the stick at state q (its tip is the end)."""
    start, end, _ = forward_kinematics(stick, q).link_segments()
    return camera.project(np.stack([start[0], end[0]]))


def axis_normal(a, b):
    d = (b - a) / np.linalg.norm(b - a)
    return np.array([-d[1], d[0]])


def measure(image, stick, camera, q_predict, **options):
    return measure_features(image, camera, stick, forward_kinematics(stick, q_predict),
                            FeatureOptions(**options))


def test_line_edges_and_tip_are_accurate_from_a_wrong_prediction(stick, flat_camera,
                                                                  stick_state, capsule_image):
    rng = np.random.default_rng(0)
    edge_errors = []
    for _ in range(6):
        x, y, angle = rng.uniform(-40, 0), rng.uniform(-20, 20), rng.uniform(-np.pi, np.pi)
        a, b = truth(stick, flat_camera, stick_state(x, y, angle))
        image = capsule_image(a, b, RADIUS, noise=3.0, rng=rng)
        q_guess = stick_state(x + rng.uniform(-4, 4), y + rng.uniform(-4, 4),
                              angle + rng.uniform(-0.08, 0.08))
        meas = measure(image, stick, flat_camera, q_guess)
        assert meas.link_valid[0] and meas.link_reason[0] == "ok"
        assert (meas.n_edges[0] >= 9).all()
        m, rho = meas.line[0, :2], meas.line[0, 2]
        assert abs(m @ a - rho) < 0.3 and abs(m @ b - rho) < 0.3
        assert np.isclose(np.linalg.norm(m), 1.0)
        n = axis_normal(a, b)
        offsets = meas.edge_points[0] @ n - n @ a  # (2, S) signed distance from the axis
        edge_errors.append(np.abs(offsets) - RADIUS)
        assert (offsets[0] < 0).all() and (offsets[1] > 0).all()
        assert meas.tip_valid[0]
        assert np.linalg.norm(meas.measured_tip[0] - b) < 1.0
    edge_errors = np.concatenate(edge_errors, axis=None)
    assert np.sqrt(np.mean(edge_errors**2)) < 0.2
    assert np.abs(edge_errors).max() < 0.6


def test_one_edge_fallback_when_one_side_merges_with_a_bright_region(
        stick, flat_camera, stick_state, capsule_image):
    q = stick_state(-30.0, -4.0, 0.0)  # horizontal stick, axis on y = -4 mm
    a, b = truth(stick, flat_camera, q)
    image = capsule_image(a, b, RADIUS)
    image[int(a[1]):, :] = 200.0  # everything below the axis has the finger's intensity
    meas = measure(image, stick, flat_camera, stick_state(-28.0, -2.5, 0.03))
    assert meas.link_valid[0]
    assert sorted(meas.n_edges[0].tolist())[0] == 0
    m, rho = meas.line[0, :2], meas.line[0, 2]
    assert abs(m @ a - rho) < 0.3 and abs(m @ b - rho) < 0.3
    only_side = int(np.argmax(meas.n_edges[0]))
    assert np.isfinite(meas.side_lines[0, only_side]).all()
    assert np.isnan(meas.side_lines[0, 1 - only_side]).all()


def test_sides_that_disagree_with_the_model_are_rejected(stick, flat_camera, stick_state,
                                                          capsule_image):
    q = stick_state(-30.0, 0.0, 0.3)
    a, b = truth(stick, flat_camera, q)
    too_wide = measure(capsule_image(a, b, 1.5 * RADIUS), stick, flat_camera, q)
    assert (too_wide.n_edges[0] >= 9).all()
    assert too_wide.link_reason[0] == "inconsistent-sides"
    # A thin bright streak where the prediction expects the finger's left contour, and
    # background on the right: that one "side" cannot be the finger's silhouette.
    image = np.full((flat_camera.height, flat_camera.width), 40.0)
    n = axis_normal(a, b)
    streak = capsule_image(a - RADIUS * n, b - RADIUS * n, 1.5, fg=200.0, bg=0.0)
    meas = measure(image + streak, stick, flat_camera, q)
    assert meas.n_edges[0, 0] >= 9 and meas.n_edges[0, 1] == 0
    assert meas.link_reason[0] == "background-side" and not meas.link_valid[0]


def test_no_edges_means_invalid(stick, flat_camera, stick_state):
    image = np.full((flat_camera.height, flat_camera.width), 90.0)
    meas = measure(image, stick, flat_camera, stick_state(-30.0, 0.0, 0.4))
    assert not meas.link_valid[0] and meas.link_reason[0] == "few-edges"
    assert not meas.tip_valid[0] and meas.tip_reason[0] == "few-edges"
    assert np.isnan(meas.line[0]).all() and np.isnan(meas.measured_tip[0]).all()
    assert meas.n_valid == 0


def test_dark_object_on_bright_background(stick, flat_camera, stick_state, capsule_image):
    rng = np.random.default_rng(4)
    q = stick_state(-35.0, 6.0, -0.7)
    a, b = truth(stick, flat_camera, q)
    image = capsule_image(a, b, RADIUS, fg=30.0, bg=210.0, noise=2.0, rng=rng)
    q_guess = stick_state(-33.0, 8.0, -0.65)
    meas = measure(image, stick, flat_camera, q_guess, bright_object=False)
    assert meas.link_valid[0] and meas.tip_valid[0]
    m, rho = meas.line[0, :2], meas.line[0, 2]
    assert abs(m @ a - rho) < 0.3 and abs(m @ b - rho) < 0.3
    assert np.linalg.norm(meas.measured_tip[0] - b) < 1.0
    wrong = measure(image, stick, flat_camera, q_guess)
    assert not wrong.link_valid[0] and not wrong.tip_valid[0]


def test_uint8_float_and_rgb_images_give_the_same_result(stick, flat_camera, stick_state,
                                                         capsule_image):
    q = stick_state(-30.0, 3.0, 0.2)
    a, b = truth(stick, flat_camera, q)
    grey = np.round(capsule_image(a, b, RADIUS, noise=3.0, rng=np.random.default_rng(1))
                    ).clip(0, 255).astype(np.uint8)
    m_grey = measure(grey, stick, flat_camera, q)  # uint8 pixels, read without conversion
    assert m_grey.link_valid[0] and m_grey.tip_valid[0]
    for other in (grey.astype(np.float32), np.repeat(grey[..., None], 3, axis=2)):
        m = measure(other, stick, flat_camera, q)
        np.testing.assert_array_equal(m.edge_points, m_grey.edge_points)
        np.testing.assert_array_equal(m.line, m_grey.line)
        np.testing.assert_array_equal(m.measured_tip, m_grey.measured_tip)


def test_off_image_and_foreshortened_links(stick, flat_camera, stick_state):
    image = np.zeros((flat_camera.height, flat_camera.width))
    far = measure(image, stick, flat_camera, stick_state(500.0, 0.0, 0.0))
    assert far.link_reason[0] == "off-image"
    q = stick.neutral()
    q[0:4] = [np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0]  # link along the optical axis
    q[6] = 100.0
    end_on = measure(image, stick, flat_camera, q)
    assert end_on.link_reason[0] == "foreshortened"
    assert end_on.tip_reason[0] == "foreshortened"


def test_selection_shapes_and_errors(stick, flat_camera, stick_state):
    image = np.zeros((flat_camera.height, flat_camera.width), np.uint8)
    kin = forward_kinematics(stick, stick_state(-30.0, 0.0, 0.0))
    meas = measure_features(image, flat_camera, stick, kin, FeatureOptions(slices_per_link=7),
                            links=["stick.link"], tips=[])
    assert meas.link_ids.tolist() == [0] and meas.tip_ids.shape == (0,)
    assert meas.edge_points.shape == (1, 2, 7, 2) and meas.slice_ends.shape == (1, 7, 2, 2)
    assert meas.measured_tip.shape == (0, 2)
    with pytest.raises(KeyError, match="no link"):
        measure_features(image, flat_camera, stick, kin, links=["nope"])
    with pytest.raises(ValueError, match="expected one of tip"):
        measure_features(image, flat_camera, stick, kin, tips=["stick.link"])
    with pytest.raises(CameraError, match="200x160"):
        measure_features(image[:-1], flat_camera, stick, kin)
    batch = forward_kinematics(stick, np.stack([stick.neutral()] * 2))
    with pytest.raises(StateError, match="one state"):
        measure_features(image, flat_camera, stick, batch)


@pytest.mark.parametrize("bad", [dict(window_px=0.0), dict(slices_per_link=1),
                                 dict(min_edge_points=1), dict(end_margin=0.5),
                                 dict(robust="ransac"), dict(tip_end="cube"),
                                 dict(min_tip_edges=4), dict(min_contrast=-1.0)])
def test_options_are_validated(bad):
    with pytest.raises(ValueError, match="FeatureOptions"):
        FeatureOptions(**bad)
