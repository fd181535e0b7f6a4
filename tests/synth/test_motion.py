"""Motion-script helpers: minimum-jerk keyframe paths, palm quaternions, image speed."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes import load_model
from digiteyes.camera import Camera, Rig
from digiteyes.kinematics.rotations import matrix_from_quaternion
from digiteyes.synth.motion import (
    image_speed,
    keyframe_path,
    min_jerk,
    palm_quaternions,
    random_keyframe_path,
)


def test_min_jerk_profile():
    s = np.linspace(0, 1, 2001)
    f = min_jerk(s)
    assert f[0] == 0.0 and f[-1] == 1.0 and np.all(np.diff(f) >= 0)
    slope = np.gradient(f, s)
    assert abs(slope.max() - 1.875) < 1e-3 and abs(slope[0]) < 1e-3 and abs(slope[-1]) < 1e-3
    np.testing.assert_array_equal(min_jerk([-1.0, 2.0]), [0.0, 1.0])


def test_keyframe_path_passes_through_keys_and_stops_there():
    times = np.array([0.0, 10.0, 25.0])
    keys = np.array([[0.0, 1.0], [5.0, -1.0], [2.0, 3.0]])
    t = np.linspace(-5, 30, 3501)
    path = keyframe_path(times, keys, t)
    for time, key in zip(times, keys, strict=True):
        np.testing.assert_allclose(path[np.argmin(np.abs(t - time))], key, atol=1e-12)
    velocity = np.gradient(path, t, axis=0)
    for time in times:
        assert np.abs(velocity[np.argmin(np.abs(t - time))]).max() < 1e-3
    np.testing.assert_array_equal(path[t < 0], np.broadcast_to(keys[0], path[t < 0].shape))
    np.testing.assert_array_equal(path[t > 25], np.broadcast_to(keys[-1], path[t > 25].shape))
    # between keys the path stays on the straight segment
    middle = path[(t > 10) & (t < 25)]
    direction = (keys[2] - keys[1]) / np.linalg.norm(keys[2] - keys[1])
    offset = middle - keys[1]
    np.testing.assert_allclose(offset - np.outer(offset @ direction, direction), 0, atol=1e-12)


@pytest.mark.parametrize(("times", "values"), [([0, 0, 1], [1, 2, 3]), ([0, 1], [1, 2, 3])])
def test_keyframe_path_rejects_bad_keys(times, values):
    with pytest.raises(ValueError):
        keyframe_path(times, np.array(values, dtype=float), np.arange(3))


def test_random_keyframe_path_is_seeded_and_bounded():
    a = random_keyframe_path(np.random.default_rng(3), 100, [-1, 0], [1, 5], 10, 20)
    b = random_keyframe_path(np.random.default_rng(3), 100, [-1, 0], [1, 5], 10, 20)
    np.testing.assert_array_equal(a, b)
    assert a.shape == (100, 2) and np.all(a >= [-1, 0]) and np.all(a <= [1, 5])
    np.testing.assert_array_equal(a[0], [0.0, 2.5])


def test_palm_quaternions_turn_the_rest_orientation_in_the_world():
    rest = np.diag([-1.0, 1.0, -1.0])
    rotvecs = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, np.pi / 2]])
    quat = palm_quaternions(rest, rotvecs)
    np.testing.assert_allclose(np.linalg.norm(quat, axis=1), 1.0)
    R = matrix_from_quaternion(quat)
    np.testing.assert_allclose(R[0], rest, atol=1e-12)
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(R[1], turn @ rest, atol=1e-12)


def test_image_speed_of_a_sideways_slide():
    """Sliding the two-finger hand by 2 mm per frame across an orthogonal view at depth Z
    moves every keypoint by about f * 2 / Z pixels."""
    model = load_model("two-finger")
    states = np.zeros((4, model.n_q))
    states[:, model.state_index("palm.x")] = 2.0 * np.arange(4)
    cam = Camera.look_at("top", (0, 60, 1000), (0, 60, 0), up=(0, 1, 0), focal_px=800)
    speed = image_speed(model, states, Rig((cam,)))
    assert speed[0] == 0.0
    np.testing.assert_allclose(speed[1:], 1.6, rtol=0.05)
