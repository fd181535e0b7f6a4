"""The manifold proposal and importance weights of Huang Sec. 5.1 (eq. 3-6).

From each particle ``X_t`` (PCA coordinates): project onto its nearest manifold ``L_ij``
(position ``s_t``), draw ``s_{t+1} ~ N(s_t, sigma)`` (eq. 3), place
``X~ = s b_i + (1 - s) b_j`` (eq. 4) and walk ``X ~ N(X~, Sigma)`` (eq. 5). A particle at a
basis state ``b_k`` (within ``basis_radius``) first picks one of the manifolds through
``b_k`` with equal probability: the mixture ``p_k`` of Sec. 5.1. ``s`` is reflected into
[0, 1], so samples stay between the two basis states.

The importance density is ``g = p(s | s_t) p(X | X~)``; the tracking prior ``f`` is the
random-walk dynamics ``N(X; X_t, Sigma_f)`` from the particle's own parent (the usual
single-ancestor approximation of the mixture over all parents). The weight (eq. 6) is
``f / g`` times the likelihood, computed in logs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from digiteyes.smc.manifolds import manifold_pairs, project_onto_manifolds


@dataclass(frozen=True)
class ProposalOptions:
    """sigma_s : std of ``s`` along a manifold (eq. 3; 1 = the manifold's length).
    walk_sigma : std of the random walk off the manifold (eq. 5), PCA units (rad).
    prior_sigma : std of the random-walk prior ``f``, PCA units (rad).
    basis_radius : distance to a basis state below which the mixture ``p_k`` is used.
    """

    sigma_s: float = 0.08
    walk_sigma: float = 0.06
    prior_sigma: float = 0.25
    basis_radius: float = 0.05


@dataclass(frozen=True)
class Proposal:
    """Drawn hypotheses: ``X`` (N, D), ``projected`` ``X~`` (N, D), ``pair`` (N,) the
    manifold used, ``s_from``/``s_to`` (N,), and ``log_g`` (N,) the importance density."""

    X: np.ndarray
    projected: np.ndarray
    pair: np.ndarray
    s_from: np.ndarray
    s_to: np.ndarray
    log_g: np.ndarray


def _reflect01(s: np.ndarray) -> np.ndarray:
    s = np.mod(s, 2.0)
    return np.where(s > 1.0, 2.0 - s, s)


def propose_on_manifolds(X_prev: np.ndarray, basis: np.ndarray, rng: np.random.Generator,
                         options: ProposalOptions = ProposalOptions(),
                         pairs: np.ndarray | None = None) -> Proposal:
    """Draw one hypothesis per particle ``X_prev`` (N, D) by Huang eq. 3-5."""
    X_prev = np.atleast_2d(np.asarray(X_prev, dtype=float))
    pairs = manifold_pairs(len(basis)) if pairs is None else pairs
    proj = project_onto_manifolds(X_prev, basis, pairs)
    pair, s_from = proj.pair.copy(), proj.s.copy()

    # Mixture p_k at a basis state: any manifold through b_k, equally likely.
    d_basis = np.linalg.norm(X_prev[:, None, :] - basis[None], axis=2)
    k = np.argmin(d_basis, axis=1)
    at_basis = np.flatnonzero(d_basis[np.arange(len(X_prev)), k] < options.basis_radius)
    if at_basis.size:
        # Every basis state lies on M - 1 manifolds (all pairs are listed).
        through = np.array([np.flatnonzero((pairs == kk).any(axis=1))
                            for kk in range(len(basis))])
        choice = through[k[at_basis], rng.integers(through.shape[1], size=at_basis.size)]
        pair[at_basis] = choice
        s_from[at_basis] = (pairs[choice, 0] == k[at_basis]).astype(float)

    s_to = _reflect01(s_from + options.sigma_s * rng.standard_normal(len(X_prev)))  # eq. 3
    bi, bj = basis[pairs[pair, 0]], basis[pairs[pair, 1]]
    projected = s_to[:, None] * bi + (1.0 - s_to[:, None]) * bj                     # eq. 4
    D = basis.shape[1]
    X = projected + options.walk_sigma * rng.standard_normal((len(X_prev), D))        # eq. 5
    log_g = (-0.5 * ((s_to - s_from) / options.sigma_s) ** 2
             - 0.5 * np.sum(((X - projected) / options.walk_sigma) ** 2, axis=1)
             - np.log(options.sigma_s) - D * np.log(options.walk_sigma))
    return Proposal(X, projected, pair, s_from, s_to, log_g)


def random_walk_log_prior(X: np.ndarray, X_prev: np.ndarray, sigma: float) -> np.ndarray:
    """``log f`` (N,): isotropic Gaussian random walk from each particle's parent, up to a
    constant."""
    return -0.5 * np.sum(((X - X_prev) / sigma) ** 2, axis=1)


def importance_log_weights(log_likelihood: np.ndarray, log_f: np.ndarray,
                           log_g: np.ndarray) -> np.ndarray:
    """Huang eq. 6 in logs: ``log pi = log f - log g + log p(Z | X)``."""
    return log_f - log_g + log_likelihood
