"""keypoints: joint bases, tip centres and the palm centre, single states and batches."""

from __future__ import annotations

import numpy as np

from digiteyes.kinematics import forward_kinematics, load_model
from digiteyes.kinematics.keypoints import keypoint_names, keypoints


def test_hand_keypoints_names_and_neutral_positions():
    hand = load_model("hand")
    names, points = keypoints(hand, forward_kinematics(hand, hand.neutral()))
    assert names == keypoint_names(hand)
    assert len(names) == 21 and points.shape == (1, 21, 3)
    assert names[0] == "palm" and "index.proximal.base" in names and "thumb.tip" in names
    by_name = dict(zip(names, points[0], strict=True))
    # Appendix A: MCP anchors at x = 31, 9, -6, -26 mm, fingers along +y, palm centre at the
    # box centre given in the model file
    for finger, x in (("index", 31), ("middle", 9), ("ring", -6), ("little", -26)):
        assert abs(by_name[f"{finger}.proximal.base"][0] - x) < 1e-9
    np.testing.assert_allclose(by_name["palm"], hand.link("palm").centre, atol=1e-12)
    np.testing.assert_allclose(by_name["index.tip"] - by_name["index.proximal.base"],
                               [0.0, 45 + 26 + 24, 0.0], atol=1e-9)


def test_batch_keypoints_match_single_states():
    hand = load_model("hand")
    rng = np.random.default_rng(2)
    Q = np.tile(hand.neutral(), (4, 1))
    Q[:, 4:7] = rng.uniform(-50, 50, (4, 3))
    Q[:, 7:] = rng.uniform(-0.5, 0.5, (4, 21))
    _, batch = keypoints(hand, forward_kinematics(hand, Q))
    assert batch.shape == (4, 21, 3)
    for n in range(4):
        _, single = keypoints(hand, forward_kinematics(hand, Q[n]))
        np.testing.assert_allclose(batch[n], single[0], atol=1e-12)
    kin = forward_kinematics(hand, Q)
    start, _, link_idx = kin.link_segments()
    tips, tip_idx = kin.tip_centres()
    np.testing.assert_allclose(batch[:, link_idx], start, atol=1e-12)
    np.testing.assert_allclose(batch[:, tip_idx], tips, atol=1e-12)
