"""Palm pose refinement by annealed local search on the frame's likelihood.

ICP of the palm outline (Huang Sec. 4.1) pins the in-plane pose well and the tilt
poorly: three sides of a rectangle say little about rotation out of the image plane. The
fingers say more, since they hang off the palm: a tilted palm moves every finger patch.
This step scores palm poses by the full likelihood of the frame with the fingers held at
the best hypothesis (Huang Sec. 5.2, every finger patch and its occlusion map) plus the
palm outline's own edge term (the same per-point factor on points along the outline),
and keeps the best of a few rounds of random perturbations of shrinking size (the M-step
of Huang Sec. 3 done by search rather than by ICP). Every draw comes from the caller's
``numpy.random.Generator``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from digiteyes.camera import Camera
from digiteyes.kinematics import KinematicModel, forward_kinematics
from digiteyes.kinematics.rotations import quaternion_from_rotvec, quaternion_multiply
from digiteyes.smc.likelihood import (
    EdgeLookup,
    FingerGeometry,
    LikelihoodOptions,
    finger_log_likelihood,
)


@dataclass(frozen=True)
class PalmSearchOptions:
    """Settings of :func:`search_palm_pose`.

    rounds : perturbation rounds (0: off); samples : poses scored per round.
    sigma_deg, sigma_mm : spread of the first round's rotation (palm frame, deg) and
        translation (world, mm); each later round halves them.
    outline_points : points sampled along the palm outline for its edge term.
    outline_check_fraction, outline_check_px : the tracker drops the outline term for a
        track when, on its first frame at the state it starts from, fewer than this
        fraction of the outline points lie within ``outline_check_px`` of an edge (the
        hand's palm is not drawn like the model's: a fleshier palm, a wrist, a sleeve);
        0 keeps it always.
    """

    rounds: int = 3
    samples: int = 48
    sigma_deg: float = 2.0
    sigma_mm: float = 1.5
    outline_points: int = 40
    outline_check_fraction: float = 0.5
    outline_check_px: float = 4.0


def palm_outline_samples(geometry: FingerGeometry, count: int) -> np.ndarray:
    """(count, 3) points evenly spaced along the palm outline (palm shape frame, mm)."""
    corners = geometry.palm_outline
    sides = np.roll(corners, -1, axis=0) - corners
    lengths = np.linalg.norm(sides, axis=1)
    s = (np.arange(count) + 0.5) / count * lengths.sum()
    side = np.minimum(np.searchsorted(np.cumsum(lengths), s, side="right"), 3)
    start = np.concatenate([[0.0], np.cumsum(lengths)[:-1]])
    t = (s - start[side]) / lengths[side]
    return corners[side] + t[:, None] * sides[side]


def outline_log_score(model: KinematicModel, geometry: FingerGeometry, q: np.ndarray,
                      cameras: tuple[Camera, ...] | list[Camera],
                      lookups: list[EdgeLookup] | tuple[EdgeLookup, ...],
                      points: np.ndarray) -> np.ndarray:
    """Sum over cameras and outline ``points`` (P, 3) of the lookup's per-point log factor
    (:class:`EdgeLookup`, Huang Sec. 5.2) for states ``q`` (N, n_q); points outside the
    image count 0."""
    T = forward_kinematics(model, np.atleast_2d(q)).T_world_shape[:, geometry.palm_row]
    world = points @ T[:, :3, :3].transpose(0, 2, 1) + T[:, None, :3, 3]
    total = np.zeros(len(world))
    for camera, lookup in zip(cameras, lookups, strict=True):
        uv = camera.project(world.reshape(-1, 3)).reshape(len(world), -1, 2)
        total += lookup.at(uv)[0].sum(axis=1)
    return total


def perturbed_palms(model: KinematicModel, q: np.ndarray, rng: np.random.Generator, count: int,
                    sigma_deg: float, sigma_mm: float) -> np.ndarray:
    """(count, n_q) copies of state ``q`` with the root pose perturbed: a rotation vector
    of std ``sigma_deg`` per axis in the palm frame, a translation of std ``sigma_mm`` per
    world axis."""
    i = model.base_state
    Q = np.repeat(np.asarray(q, dtype=float)[None], count, axis=0)
    rotvec = np.radians(sigma_deg) * rng.standard_normal((count, 3))
    Q[:, i:i + 4] = quaternion_multiply(Q[0, i:i + 4], quaternion_from_rotvec(rotvec))
    Q[:, i + 4:i + 7] += sigma_mm * rng.standard_normal((count, 3))
    return Q


def outline_edge_fraction(model: KinematicModel, geometry: FingerGeometry, q: np.ndarray,
                          camera: Camera, lookup: EdgeLookup, points: np.ndarray,
                          max_px: float) -> float:
    """Fraction of the palm outline ``points`` (P, 3) of state ``q`` (n_q,) that project
    into ``camera``'s image within ``max_px`` of an edge (:attr:`EdgeLookup.distance`)."""
    T = forward_kinematics(model, np.atleast_2d(q)).T_world_shape[0, geometry.palm_row]
    near = lookup.at(camera.project(points @ T[:3, :3].T + T[:3, 3]))[1] <= max_px
    return float(near.sum()) / len(points) if len(points) else 0.0


def search_palm_pose(model: KinematicModel, geometry: FingerGeometry, q: np.ndarray,
                     cameras: tuple[Camera, ...] | list[Camera], edge_maps: list[np.ndarray],
                     lookups: list[EdgeLookup], rng: np.random.Generator,
                     options: PalmSearchOptions = PalmSearchOptions(),
                     likelihood: LikelihoodOptions | None = None
                     ) -> tuple[np.ndarray, float, float]:
    """The best palm pose found around state ``q`` (n_q,) (fingers fixed).

    Returns the state (n_q,) with the new root pose, its score and the score of ``q``
    (finger log-likelihood + outline term; the state is ``q`` itself when nothing beat it).
    """
    likelihood = likelihood or LikelihoodOptions()
    points = palm_outline_samples(geometry, options.outline_points)

    def score(Q: np.ndarray) -> np.ndarray:
        return (finger_log_likelihood(model, geometry, Q, cameras, edge_maps, likelihood,
                                      lookups).log_likelihood
                + outline_log_score(model, geometry, Q, cameras, lookups, points))

    best = np.array(q, dtype=float)
    start_score = best_score = float(score(best[None])[0])
    for r in range(options.rounds):
        shrink = 0.5 ** r
        Q = perturbed_palms(model, best, rng, options.samples, options.sigma_deg * shrink,
                            options.sigma_mm * shrink)
        s = score(Q)
        k = int(np.argmax(s))
        if s[k] > best_score:
            best, best_score = Q[k], float(s[k])
    return best, best_score, start_score
