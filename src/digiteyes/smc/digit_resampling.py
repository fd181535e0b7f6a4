"""Per-digit resampling: each digit's joints drawn by that digit's own likelihood factor.

Huang et al. resample whole hypotheses by the whole likelihood (Sec. 5.1). The edge
likelihood of Sec. 5.2 is nearly a product over the digits (a patch's edge points depend
on its own digit, and on the others only through the occlusion map), while the weights of
a 7-D particle set collapse onto one particle in every frame (an effective sample size
of 1-2 on ``natural``): a finger that one hypothesis has right and another wrong is kept
or lost with whichever hypothesis wins on the other four digits. Resampling the digits
one at a time keeps, for every digit, the hypotheses that explain that digit's edges
(the factored resampling of partitioned sampling, MacCormick & Isard, ECCV 2000, applied
to all digits at once). The recombined joint vectors are mapped back into the PCA space
(Huang eq. 1), so every particle stays a state the prior can describe. Ours, not in the
paper; measured in docs/divide-and-conquer.md, "Per-digit resampling".
"""

from __future__ import annotations

import numpy as np

from digiteyes.errors import DigitEyesError
from digiteyes.kinematics.anatomy import DIGITS
from digiteyes.smc.configuration import ConfigurationSpace
from digiteyes.smc.resample import normalised_weights, systematic_resample


def digit_of(names: tuple[str, ...] | list[str]) -> np.ndarray:
    """The digit (index into :data:`~digiteyes.kinematics.anatomy.DIGITS`, thumb first)
    of each joint or link name (``"index.pip"``, ``"thumb.distal"``), (K,); raises
    :class:`DigitEyesError` for a name of no digit."""
    out = []
    for name in names:
        digit = name.split(".", 1)[0]
        if digit not in DIGITS:
            raise DigitEyesError(f"per-digit resampling: {name!r} belongs to no digit "
                                 f"({', '.join(DIGITS)})")
        out.append(DIGITS.index(digit))
    return np.array(out, dtype=int)


def recombine(space: ConfigurationSpace, coordinates: np.ndarray, parents: np.ndarray
              ) -> np.ndarray:
    """Hypotheses (n, D) in PCA coordinates whose digit ``d`` has the joints of hypothesis
    ``parents[:, d]`` of ``coordinates`` (N, D); ``parents`` (n, 5) indices, thumb first.
    The joint vectors are mapped back into the space (its least-squares coordinates)."""
    coordinates = np.atleast_2d(np.asarray(coordinates, dtype=float))
    parents = np.atleast_2d(np.asarray(parents, dtype=int))
    rows, index = np.unique(parents, return_inverse=True)  # only the hypotheses drawn
    joints = space.to_joints(coordinates[rows])
    index = index.reshape(parents.shape)
    digit = digit_of(space.joint_names)
    out = np.empty((len(parents), joints.shape[1]))
    for d in range(len(DIGITS)):
        columns = digit == d
        out[:, columns] = joints[index[:, d]][:, columns]
    return space.to_coordinates(out)


def _checked(coordinates: np.ndarray, digit_log_likelihood: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
    coordinates = np.atleast_2d(np.asarray(coordinates, dtype=float))
    factors = np.asarray(digit_log_likelihood, dtype=float)
    if factors.shape != (len(coordinates), len(DIGITS)):
        raise DigitEyesError(f"per-digit resampling: expected ({len(coordinates)}, "
                             f"{len(DIGITS)}) digit log-likelihoods, got {factors.shape}")
    return coordinates, factors


def digit_resample(space: ConfigurationSpace, coordinates: np.ndarray,
                   digit_log_likelihood: np.ndarray, rng: np.random.Generator, n: int,
                   temperature: float = 1.0) -> np.ndarray:
    """``n`` hypotheses (n, D) in PCA coordinates, each digit's joints drawn from the
    hypotheses ``coordinates`` (N, D) by systematic resampling on that digit's
    ``digit_log_likelihood`` (N, 5) divided by ``temperature``: one uniform draw from
    ``rng`` per digit, thumb first. Pure: same inputs, same output."""
    coordinates, factors = _checked(coordinates, digit_log_likelihood)
    parents = np.column_stack([
        systematic_resample(normalised_weights(factors[:, d] / temperature), rng, n)
        for d in range(len(DIGITS))])
    return recombine(space, coordinates, parents)


def best_of_each_digit(space: ConfigurationSpace, coordinates: np.ndarray,
                       digit_log_likelihood: np.ndarray) -> np.ndarray:
    """The hypothesis (D,) whose every digit has the joints of the hypothesis of
    ``coordinates`` (N, D) that explains that digit best (``digit_log_likelihood``
    (N, 5)): the product of the per-digit maxima, where the particle set's best whole
    hypothesis maximises the product only over the hypotheses drawn."""
    coordinates, factors = _checked(coordinates, digit_log_likelihood)
    return recombine(space, coordinates, np.argmax(factors, axis=0)[None])[0]


__all__ = ["best_of_each_digit", "digit_of", "digit_resample", "recombine"]
