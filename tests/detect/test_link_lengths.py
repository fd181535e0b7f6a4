"""Link lengths of the user's hand: triangulation through a rig, the 15 digit segments,
and a model that takes measured lengths exactly."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.camera import Camera, Rig
from digiteyes.detect.hand21 import model_anchors
from digiteyes.detect.link_lengths import (
    DIGIT_SEGMENTS,
    SEGMENT_NAMES,
    measured_lengths,
    model_lengths,
    segment_lengths,
    triangulate,
    with_link_lengths,
)
from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import forward_kinematics


@pytest.fixture(scope="module")
def rig() -> Rig:
    """Two 640x480 cameras 450 mm from the hand, 160 mm apart, verged on the origin."""
    return Rig([Camera.look_at("left", eye=(-80, 0, 450), target=(0, 30, 0), up=(0, -1, 0)),
                Camera.look_at("right", eye=(80, 0, 450), target=(0, 30, 0), up=(0, -1, 0))])


def points_of(model, q):
    rows, points = model_anchors(model)
    return forward_kinematics(model, q).points(rows, points)


def test_segments_cover_each_digit_base_to_tip():
    assert len(DIGIT_SEGMENTS) == len(SEGMENT_NAMES) == 15
    assert SEGMENT_NAMES[3] == "index.mcp-pip" and SEGMENT_NAMES[2] == "thumb.ip-tip"
    assert {k for pair in DIGIT_SEGMENTS for k in pair} == set(range(1, 21))


def test_model_lengths_are_the_distances_of_its_own_keypoints(hand, posed):
    for seed in range(3):
        np.testing.assert_allclose(segment_lengths(points_of(hand, posed(hand, seed))),
                                   model_lengths(hand), atol=1e-9)


def test_a_model_takes_the_lengths_it_is_given(hand, posed):
    rng = np.random.default_rng(0)
    wanted = model_lengths(hand) * rng.uniform(0.8, 1.2, 15)
    mine = with_link_lengths(hand, wanted, name="mine")
    assert mine.name == "mine" and mine.n_q == hand.n_q
    np.testing.assert_allclose(model_lengths(mine), wanted, atol=1e-9)
    for seed in range(3):  # at any pose, not only the straight hand
        q = posed(hand, seed)
        np.testing.assert_allclose(segment_lengths(points_of(mine, q)), wanted, atol=1e-9)
        # the palm (wrist, thumb base, four MCPs) does not move
        np.testing.assert_allclose(points_of(mine, q)[[0, 1, 5, 9, 13, 17]],
                                   points_of(hand, q)[[0, 1, 5, 9, 13, 17]], atol=1e-9)
    np.testing.assert_array_equal([link.radius for link in mine.links],
                                  [link.radius for link in hand.links])


def test_lengths_the_model_cannot_take_are_refused(hand):
    lengths = model_lengths(hand)
    lengths[2] = 5.0  # shorter than the thumb tip's fixed offset
    with pytest.raises(DigitEyesError, match=r"thumb\.ip-tip"):
        with_link_lengths(hand, lengths)
    with pytest.raises(DigitEyesError, match="15 finite"):
        with_link_lengths(hand, lengths[:14])


def test_triangulation_is_exact_without_noise_and_needs_two_views(hand, posed, rig):
    truth = points_of(hand, posed(hand, 1))
    pixels = [cam.project(truth) for cam in rig]
    np.testing.assert_allclose(triangulate(rig, pixels), truth, atol=1e-6)
    hidden = [pixels[0].copy(), pixels[1]]
    hidden[0][7] = np.nan
    out = triangulate(rig, hidden)
    assert np.isnan(out[7]).all() and np.isfinite(np.delete(out, 7, axis=0)).all()
    assert np.isnan(triangulate(rig, [pixels[0], None])).all()
    with pytest.raises(DigitEyesError, match="one keypoint array per camera"):
        triangulate(rig, pixels[:1])


def test_a_user_hand_is_measured_from_noisy_stereo_keypoints(hand, posed, rig):
    """A hand with its own segment lengths (0.85-1.15 of the model's), seen in 12 poses by
    two cameras with 1 px keypoint noise: the medians come within 2 mm of the truth."""
    rng = np.random.default_rng(7)
    true_lengths = model_lengths(hand) * rng.uniform(0.85, 1.15, 15)
    user = with_link_lengths(hand, true_lengths)
    frames = []
    for seed in range(12):
        truth = points_of(user, posed(hand, seed, flex=(0.0, 0.4)))
        pixels = [cam.project(truth) + rng.normal(0.0, 1.0, (21, 2)) for cam in rig]
        frames.append(triangulate(rig, pixels))
    lengths, counts = measured_lengths(np.array(frames))
    assert (counts == 12).all()
    assert np.abs(lengths - true_lengths).max() < 2.0
    assert np.abs(model_lengths(hand) - true_lengths).max() > 5.0  # the test can fail
    frames[0][:] = np.nan
    assert (measured_lengths(np.array(frames))[1] == 11).all()
    with pytest.raises(DigitEyesError, match=r"index\.mcp-pip"):
        measured_lengths(np.full((2, 21, 3), np.nan))
