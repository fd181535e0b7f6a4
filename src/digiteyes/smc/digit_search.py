"""Digit-by-digit search: move one digit at a time along its curl, keep what the frame
prefers.

The likelihood of Huang Sec. 5.2 is (nearly) a product over digits: each finger patch's
edge points depend on its own digit's joints and, through the occlusion map, a little on
its neighbours'. A particle set in the joint 7-D space has to find a move of several
digits at once by chance; with a few hundred particles and weights that collapse onto
one particle it misses large moves of a single digit (a finger opening from a full curl
while the others stay, docs/divide-and-conquer.md). Searching the digits one at a time
is the old remedy for such a product (partitioned sampling, MacCormick & Isard 2000),
done here deterministically on the best hypothesis:

* every digit's joints move along the direction from its fully extended to its fully
  curled configuration (the basis configurations of Huang Sec. 2, per digit) by each
  step of :attr:`DigitSearchOptions.steps` (fractions of that path), the other digits
  held; every candidate is mapped into the PCA space (so it stays a state the prior can
  describe) and all of them are scored in one batch;
* each digit's best step is kept if it beats the current hypothesis; the kept steps are
  then tried together, and the better of "together" and "the best single step" wins;
* :attr:`DigitSearchOptions.palms`: all of this is done under a few palm poses at once
  (the current one and random perturbations of it), and the best pair of palm and
  fingers wins. The fingers hang off the palm: a palm tilted a little and a finger bent
  a little can draw the same edges, and searching one while the other is held cannot
  leave such a ridge (scoring palm and fingers together, docs/divide-and-conquer.md);
* :attr:`DigitSearchOptions.passes` repeats this from the result, under its palm.

The search only ever returns a hypothesis at least as likely as the one it started from.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from digiteyes.kinematics.anatomy import DIGITS, digit_joint_angles
from digiteyes.smc.configuration import ConfigurationSpace


@dataclass(frozen=True)
class DigitSearchOptions:
    """Settings of :func:`search_digits`.

    steps : moves tried for each digit, as fractions of its path from fully extended
        (0) to fully curled (1); negative values open the digit.
    passes : search rounds (0: off).
    palms : palm poses the moves are tried under: the current one and ``palms - 1``
        random perturbations of it (1: the palm held).
    palm_sigma_deg, palm_sigma_mm : spread of the perturbed palms' rotation (palm frame,
        deg) and translation (world, mm).
    """

    steps: tuple[float, ...] = (-0.6, -0.3, -0.12, 0.12, 0.3, 0.6)
    passes: int = 1
    palms: int = 9
    palm_sigma_deg: float = 2.0
    palm_sigma_mm: float = 1.5

    def __post_init__(self) -> None:
        for name, low in (("passes", 0), ("palms", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ValueError(f"digit_search.{name} must be an integer of at least {low}, "
                                 f"got {value!r}")
        try:
            steps = np.asarray(self.steps, dtype=float)
        except (TypeError, ValueError):
            steps = np.array([np.nan])
        if steps.ndim != 1 or not steps.size or not np.isfinite(steps).all():
            raise ValueError(f"digit_search.steps must be a list of finite numbers, got "
                             f"{self.steps!r}")
        if not (self.palm_sigma_deg >= 0 and self.palm_sigma_mm >= 0):
            raise ValueError("digit_search.palm_sigma_deg and palm_sigma_mm must not be "
                             "negative")


def digit_curl_directions(space: ConfigurationSpace) -> np.ndarray:
    """(5, J) joint-angle change (rad) from each digit's fully extended to its fully curled
    configuration (thumb, index, middle, ring, little); joints of the other digits 0."""
    column = {name: j for j, name in enumerate(space.joint_names)}
    out = np.zeros((len(DIGITS), len(space.joint_names)))
    for d, digit in enumerate(DIGITS):
        closed = digit_joint_angles(digit, False)
        for name, value in digit_joint_angles(digit, True).items():
            if name in column:
                out[d, column[name]] = closed[name] - value
    return out


def search_digits(space: ConfigurationSpace, coordinates: np.ndarray,
                  score: Callable[[np.ndarray, np.ndarray], np.ndarray],
                  options: DigitSearchOptions = DigitSearchOptions(),
                  directions: np.ndarray | None = None, n_palms: int = 1
                  ) -> tuple[np.ndarray, int, float, float]:
    """The best hypothesis found from ``coordinates`` (D,) by moving one digit at a time,
    under each of ``n_palms`` palm poses held by the caller.

    ``score(X, palm)`` maps PCA coordinates (N, D) and palm indices (N,) (0 is the current
    palm) to log scores (N,). The first pass tries every move under every palm in one
    batch and keeps the best (palm, hypothesis) pair; later passes keep that palm.
    Returns the coordinates (D,), the palm index, their score and the score of the start
    (``coordinates`` under palm 0).
    """
    directions = digit_curl_directions(space) if directions is None else directions
    steps = np.asarray(options.steps, dtype=float)
    n_digits, n_steps = len(directions), len(steps)
    best, palm = np.asarray(coordinates, dtype=float).copy(), 0
    palms = np.arange(n_palms)
    start_score = best_score = None
    for _ in range(options.passes):
        joints = space.to_joints(best)
        moves = steps[None, :, None] * directions[:, None, :]            # (5, S, J)
        candidates = np.concatenate([best[None], space.to_coordinates(
            np.clip(joints + moves, space.lower, space.upper).reshape(-1, len(joints)))])
        scores = score(np.tile(candidates, (len(palms), 1)),
                       np.repeat(palms, len(candidates))).reshape(len(palms), -1)
        if start_score is None:
            start_score = best_score = float(scores[0, 0])
        held, moved = scores[:, 0], scores[:, 1:].reshape(len(palms), n_digits, n_steps)
        pick = np.argmax(moved, axis=2)                                  # (P, 5)
        gain = np.take_along_axis(moved, pick[..., None], axis=2)[..., 0] > held[:, None]
        k = np.unravel_index(np.argmax(scores), scores.shape)
        choice, choice_palm, choice_score = candidates[k[1]], palms[k[0]], float(scores[k])
        several = np.flatnonzero(gain.sum(axis=1) > 1)
        if several.size:
            together = np.stack([np.clip(
                joints + (steps[pick[p, gain[p]], None] * directions[gain[p]]).sum(0),
                space.lower, space.upper) for p in several])
            x = space.to_coordinates(together)
            s = score(x, palms[several])
            j = int(np.argmax(s))
            if s[j] > choice_score:
                choice, choice_palm, choice_score = x[j], palms[several[j]], float(s[j])
        if choice_score <= best_score:
            break
        best, palm, best_score = choice, int(choice_palm), choice_score
        palms = np.array([palm])
    if start_score is None:
        start_score = best_score = float(score(best[None], np.zeros(1, dtype=int))[0])
    return best, palm, float(best_score), float(start_score)
