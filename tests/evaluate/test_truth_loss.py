"""Ground-truth loss labels and flag scores."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.errors import DigitEyesError
from digiteyes.evaluate.truth_loss import fingertips, flag_scores, truth_loss
from digiteyes.kinematics import load_model


def test_loss_thresholds_on_shifted_and_bent_hands():
    hand = load_model("hand")
    truth = np.repeat(hand.neutral()[None], 4, axis=0)
    est = truth.copy()
    x = hand.base_state + 4
    est[1, x] += 25.0  # every tip 25 mm off: mean below 30, none above 50
    est[2, x] += 35.0  # mean above 30
    est[3, hand.state_index("index.mcp")] = np.radians(90.0)  # one finger far off
    labels = truth_loss(hand, est, truth)
    assert labels.tip_names[0].endswith(".tip") and len(labels.tip_names) == 5
    assert np.allclose(labels.mean_tip_error_mm[:3], [0.0, 25.0, 35.0])
    assert labels.lost.tolist() == [False, False, True, True]
    index = labels.tip_names.index("index.tip")
    assert labels.finger_lost[3].tolist() == [i == index for i in range(5)]
    assert labels.mean_tip_error_mm[3] < 30.0  # lost by one tip alone


def test_truth_model_of_another_size():
    from digiteyes.synth.perturb import scale_model

    hand = load_model("hand")
    q = hand.neutral()[None]
    _, tips = fingertips(hand, q)
    labels = truth_loss(hand, q, q, true_model=scale_model(hand, 1.1))
    assert np.allclose(labels.tip_error_mm, 0.1 * np.linalg.norm(tips[0], axis=1))


def test_flag_scores_counts():
    scores = flag_scores([True, True, False, False, True], [True, False, True, False, True])
    assert scores["precision"] == pytest.approx(2 / 3) and scores["recall"] == pytest.approx(2 / 3)
    assert flag_scores([False], [False])["precision"] is None
    with pytest.raises(DigitEyesError):
        flag_scores([True], [True, False])


def test_an_estimate_of_the_right_size_is_not_lost():
    """The estimated hand drawn at the log's ``hand_scale``: at the true size the error
    is nil."""
    from digiteyes.synth.perturb import scale_model

    hand = load_model("hand")
    q = hand.neutral()[None]
    labels = truth_loss(hand, q, q, true_model=scale_model(hand, 1.1), hand_scale=1.1)
    np.testing.assert_allclose(labels.tip_error_mm, 0.0, atol=1e-9)
