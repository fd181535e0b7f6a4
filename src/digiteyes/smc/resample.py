"""Resampling of a weighted particle set, as pure functions of (weights, rng)."""

from __future__ import annotations

import numpy as np

from digiteyes.errors import DigitEyesError


def normalised_weights(log_weights: np.ndarray) -> np.ndarray:
    """Weights (N,) summing to 1 from log weights (max-shifted, so no overflow). Raises
    :class:`DigitEyesError` when every weight is zero or not finite."""
    log_weights = np.asarray(log_weights, dtype=float)
    finite = np.isfinite(log_weights)
    if not finite.any():
        raise DigitEyesError("every particle has zero weight (all log weights -inf or NaN)")
    w = np.zeros(len(log_weights))
    w[finite] = np.exp(log_weights[finite] - log_weights[finite].max())
    return w / w.sum()


def effective_sample_size(weights: np.ndarray) -> float:
    """``1 / sum w_n^2`` of normalised weights: N for equal weights, 1 for one particle."""
    return float(1.0 / np.sum(np.square(weights)))


def systematic_resample(weights: np.ndarray, rng: np.random.Generator,
                        n: int | None = None) -> np.ndarray:
    """Indices (n,) drawn with probabilities ``weights`` (N,) by systematic resampling:
    one uniform draw from ``rng``, then n evenly spaced pointers into the cumulative sum
    (each index appears floor(n w) or ceil(n w) times). Pure: same inputs, same output."""
    weights = np.asarray(weights, dtype=float)
    if weights.ndim != 1 or len(weights) == 0 or (weights < 0).any() or \
            not np.isfinite(weights).all() or weights.sum() <= 0:
        raise DigitEyesError("resampling needs a non-empty 1-D array of non-negative, "
                             "finite weights with a positive sum")
    n = len(weights) if n is None else int(n)
    cumulative = np.cumsum(weights / weights.sum())
    cumulative[-1] = 1.0
    pointers = (rng.uniform() + np.arange(n)) / n
    return np.searchsorted(cumulative, pointers, side="right").clip(0, len(weights) - 1)
