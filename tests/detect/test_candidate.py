"""A hand candidate found in a turned image, turned back: checked against ``numpy.rot90``
itself, pixel by pixel."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.detect.candidate import HandCandidate, bbox_of


def _marked(width: int, height: int, points: np.ndarray) -> np.ndarray:
    """An image (height, width) of zeros with pixel ``k + 1`` at integer point ``k``."""
    image = np.zeros((height, width), dtype=np.int32)
    for k, (u, v) in enumerate(points):
        image[v, u] = k + 1
    return image


def _found(image: np.ndarray, n: int) -> np.ndarray:
    """Where pixels 1..n lie in ``image`` (n, 2), (u, v)."""
    return np.array([np.argwhere(image == k + 1)[0][::-1] for k in range(n)], dtype=float)


@pytest.mark.parametrize("turns", [0, 1, 2, 3])
def test_a_candidate_in_a_turned_image_turns_back_onto_the_image(turns):
    rng = np.random.default_rng(turns)
    width, height = 37, 23
    original = np.column_stack([rng.choice(width, 21, replace=False),
                                rng.integers(0, height, 21)])
    turned_image = np.rot90(_marked(width, height, original), -turns)  # clockwise
    seen = _found(turned_image, 21)  # where a detector in the turned image finds them
    depth = rng.uniform(-30, 30, 21)
    # 3D points whose x and y axes follow the turned image's (as MediaPipe's world
    # landmarks), about an arbitrary origin
    points = np.column_stack([seen - seen.mean(axis=0), depth])
    mask = np.zeros(turned_image.shape, dtype=bool)
    mask[turned_image > 0] = True
    candidate = HandCandidate(keypoints=seen, keypoint_confidence=np.ones(21),
                              confidence=0.9, bbox=bbox_of(seen), handedness="left",
                              detector="test", keypoints_3d=points, mask=mask)

    back = candidate.unturned(turns, width, height)

    np.testing.assert_allclose(back.keypoints, original)
    assert back.bbox == bbox_of(original)
    assert back.handedness == "left"
    assert back.mask.shape == (height, width)
    np.testing.assert_array_equal(np.argwhere(back.mask)[:, ::-1][np.lexsort(
        np.argwhere(back.mask)[:, ::-1].T)], original[np.lexsort(original.T)])
    # the 3D points turn with the pixels: their x, y differences are the pixel differences
    np.testing.assert_allclose(back.keypoints_3d[:, :2] - back.keypoints_3d[0, :2],
                               original - original[0])
    np.testing.assert_allclose(back.keypoints_3d[:, 2], depth)
