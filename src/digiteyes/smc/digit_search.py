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
* :attr:`DigitSearchOptions.passes` repeats this from the result.

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
    """

    steps: tuple[float, ...] = (-0.6, -0.3, -0.12, 0.12, 0.3, 0.6)
    passes: int = 1


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
                  score: Callable[[np.ndarray], np.ndarray],
                  options: DigitSearchOptions = DigitSearchOptions(),
                  directions: np.ndarray | None = None) -> tuple[np.ndarray, float, float]:
    """The best hypothesis found from ``coordinates`` (D,) by moving one digit at a time.

    ``score`` maps PCA coordinates (N, D) to log-likelihoods (N,) (the palm held by the
    caller). Returns the coordinates (D,), their score, and the score of the start.
    """
    directions = digit_curl_directions(space) if directions is None else directions
    steps = np.asarray(options.steps, dtype=float)
    best = np.asarray(coordinates, dtype=float).copy()
    start_score = best_score = float(score(best[None])[0])
    for _ in range(options.passes):
        joints = space.to_joints(best)
        moves = steps[None, :, None] * directions[:, None, :]            # (5, S, J)
        candidates = space.to_coordinates(
            np.clip(joints + moves, space.lower, space.upper).reshape(-1, len(joints)))
        scores = score(candidates).reshape(len(directions), len(steps))
        pick = np.argmax(scores, axis=1)
        better = scores[np.arange(len(directions)), pick] > best_score
        if not better.any():
            break
        single = np.unravel_index(np.argmax(scores), scores.shape)
        choice, choice_score = candidates[np.ravel_multi_index(single, scores.shape)], \
            float(scores[single])
        if better.sum() > 1:
            together = np.clip(joints + (steps[pick[better], None] * directions[better]).sum(0),
                               space.lower, space.upper)
            x = space.to_coordinates(together)
            s = float(score(x[None])[0])
            if s > choice_score:
                choice, choice_score = x, s
        best, best_score = choice, choice_score
    return best, best_score, start_score
