"""Ground-truth track-loss labels: when is a tracker truly lost?

A frame is **truly lost** when the mean fingertip error exceeds 30 mm, or when any single
fingertip is more than 50 mm from its true position (issue 13: a single flipped finger is
a loss even when the others are right). A finger is lost when its tip error exceeds 50 mm.
Fingertips are the keypoints named ``*.tip`` (:func:`digiteyes.kinematics.keypoints.
keypoints`); the estimated tips come from the tracking model, the true ones from the model
the images were drawn from (a scaled or perturbed copy, or the same model).

:func:`flag_scores` compares a tracker's loss flags with these labels (precision and recall
of the flag as a detector of true loss).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import KinematicModel
from digiteyes.kinematics.keypoints import hand_keypoints

TRULY_LOST_MEAN_MM = 30.0
"""Mean fingertip error (mm) above which a frame is truly lost."""
TRULY_LOST_ANY_MM = 50.0
"""Error (mm) of any one fingertip above which the frame (and that finger) is lost."""


@dataclass(frozen=True)
class TruthLoss:
    """Per-frame truth about loss.

    ``tip_names`` (F,); ``tip_error_mm`` (T, F) Euclidean 3D error of each fingertip;
    ``mean_tip_error_mm`` (T,); ``finger_lost`` (T, F) bool, tip error above the any-tip
    threshold; ``lost`` (T,) bool, the frame is truly lost.
    """

    tip_names: tuple[str, ...]
    tip_error_mm: np.ndarray
    mean_tip_error_mm: np.ndarray
    finger_lost: np.ndarray
    lost: np.ndarray


def fingertips(model: KinematicModel, states: np.ndarray, hand_scale: float | np.ndarray = 1.0
               ) -> tuple[tuple[str, ...], np.ndarray]:
    """Fingertip names (F,) and world positions (T, F, 3) mm of states (T, n_q) of a hand
    ``hand_scale`` times the model's size (one scale or (T,);
    :func:`~digiteyes.kinematics.keypoints.hand_keypoints`)."""
    names, points = hand_keypoints(model, states, hand_scale)
    tips = [i for i, name in enumerate(names) if str(name).endswith(".tip")]
    if not tips:
        raise DigitEyesError(f"model {model.name!r} has no fingertips (links named *.tip)")
    return tuple(str(names[i]) for i in tips), np.asarray(points)[:, tips]


def truth_loss(model: KinematicModel, estimated: np.ndarray, true_states: np.ndarray,
               true_model: KinematicModel | None = None,
               mean_mm: float = TRULY_LOST_MEAN_MM,
               any_mm: float = TRULY_LOST_ANY_MM,
               hand_scale: float | np.ndarray = 1.0) -> TruthLoss:
    """Loss labels of estimated states (T, n_q) of ``model`` (a hand ``hand_scale`` times
    its size, e.g. a state log's column) against true states (T, n_q) of ``true_model``
    (default ``model``): frame lost when the mean fingertip error exceeds ``mean_mm`` or
    any fingertip error exceeds ``any_mm``. Raises :class:`DigitEyesError` when the state
    arrays or the two models' fingertips do not match."""
    est, true = np.atleast_2d(estimated), np.atleast_2d(true_states)
    if est.shape[0] != true.shape[0]:
        raise DigitEyesError(f"truth_loss: {est.shape[0]} estimated states but "
                             f"{true.shape[0]} true states")
    names, tips = fingertips(model, est, hand_scale)
    true_names, true_tips = fingertips(true_model or model, true)
    if names != true_names:
        raise DigitEyesError(f"truth_loss: the models' fingertips differ: {names} and "
                             f"{true_names}")
    error = np.linalg.norm(tips - true_tips, axis=2)
    mean = error.mean(axis=1)
    finger_lost = error > any_mm
    return TruthLoss(names, error, mean, finger_lost, (mean > mean_mm) | finger_lost.any(1))


def flag_scores(flagged: np.ndarray, lost: np.ndarray) -> dict[str, float | int | None]:
    """Precision and recall of loss flags (T,) bool against true loss (T,) bool, with the
    counts: ``true_positive``, ``false_positive``, ``false_negative``, ``lost_frames``,
    ``flagged_frames``; precision (recall) is None when nothing is flagged (lost)."""
    flagged, lost = np.asarray(flagged, dtype=bool), np.asarray(lost, dtype=bool)
    if flagged.shape != lost.shape:
        raise DigitEyesError(f"flag_scores: flags of shape {flagged.shape} and labels of "
                             f"shape {lost.shape}")
    tp = int(np.count_nonzero(flagged & lost))
    fp = int(np.count_nonzero(flagged & ~lost))
    fn = int(np.count_nonzero(~flagged & lost))
    return {"precision": tp / (tp + fp) if tp + fp else None,
            "recall": tp / (tp + fn) if tp + fn else None,
            "true_positive": tp, "false_positive": fp, "false_negative": fn,
            "lost_frames": int(lost.sum()), "flagged_frames": int(flagged.sum())}
