"""The hand's size from the first frame's features, at a known start state.

A track that starts from the hand's true pose (a dataset's initial state, measured with
the images) knows where the palm is, so the projected finger lengths and positions set
the hand's size even in one camera: a model ``s`` times the model file's size
(:func:`~digiteyes.kinematics.scaling.scaled_model`, scaled about its base) posed at the
start puts the joints and fingertips where the image shows them only at the hand's own
``s``. The size is the one of :data:`START_SCALES` whose feature cost at the start state
is least. The cost is the feature residuals' (thesis Sec. 2.5; no link-width rows: the
widths say how thick the fingers are drawn, not how long they are) plus, for every
requested feature that finds no edge in its window, the cost of a residual of
:data:`INVALID_RESIDUAL_PX`: without it a size whose features miss their windows would
look cheap.

Measured by ``digiteyes bench hand-size`` (:mod:`digiteyes.benchmarks.hand_size`; docs/
features.md, "The hand's size"): at the model file's size the least cost lies within a
grid step or two of 1 on our drawing and within 0.06 of it on the independent flesh hand,
while hands 0.9 and 1.1 times the size are found within 0.04, which is why a size other
than the model file's must explain the frame markedly better (:data:`MIN_GAIN`) and lie
outside the measurement's own spread (:data:`DEAD_BAND`). :func:`hand_size_at` is what
the feature, template and divide-and-conquer trackers call on their first frame.

A start fitted from the images (``--init auto``) has the depth the fit assumed for the
model's size: one camera cannot tell a larger hand further away, so ``digiteyes track``
measures the size only from a given start (:mod:`digiteyes.track_job`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from digiteyes.camera import Rig
from digiteyes.features import FeatureOptions, feature_residuals, measure_features
from digiteyes.features.selection import feature_names
from digiteyes.features.slices import prepare_image
from digiteyes.kinematics import KinematicModel, forward_kinematics
from digiteyes.kinematics.scaling import scaled_model
from digiteyes.solvers.robust import RobustLoss, robust_cost

START_SCALES = np.round(np.linspace(0.8, 1.2, 21), 2)  # step 0.02
"""Hand sizes tried on the first frame, relative to the model file (adult hand lengths
spread by about 8 % about their mean; the grid covers two and a half spreads)."""
INVALID_RESIDUAL_PX = 10.0
"""A requested feature without an edge in its window costs what a residual of this many
pixels costs (half the default search window)."""
MIN_GAIN = 0.25
"""A size other than the model file's is taken only when its cost is at least this
fraction below the cost at the model file's size: on a hand drawn unlike the model the
cost's minimum moves by itself (the flesh hand of the model's size: up to 0.94, at most
20 % below the cost at 1), while a hand of another size shows a clear minimum (0.9 and
1.1 of the size: at least 28 % below; docs/features.md, "The hand's size")."""
DEAD_BAND = 0.05
"""A size other than the model file's is taken only when it also lies more than this
from 1: one feature slipping into or out of
its window moves the minimum by a grid step or two on our own drawing at the model's size
(0.98 or 1.02, up to 39 % below the cost at 1); hands 0.9 and 1.1 times the size were
found at 0.86-0.94 and 1.06-1.14. A hand within 5 % of the model's keeps its size."""


FeatureEvaluation = Callable[[KinematicModel], tuple[np.ndarray, int]]
"""The feature residuals (px) at the start state of a model of the hand, and how many of
the requested features found an edge (:func:`feature_evaluation`)."""


def feature_evaluation(rig: Rig, images: Sequence[np.ndarray], q: np.ndarray,
                       features: FeatureOptions, link_names: Sequence[str],
                       tip_names: Sequence[str], axis_points: int = 2,
                       palm_iterations: int = 0) -> FeatureEvaluation:
    """The :data:`FeatureEvaluation` of state ``q`` (n_q,; translation in mm) in
    ``images`` (one prepared grey image per camera,
    :func:`~digiteyes.features.slices.prepare_image`, float32; rig order): the line and
    tip residuals of the feature tracker (thesis Sec. 2.5, no width rows) of the links
    and tips named, after ``palm_iterations`` Gauss-Newton steps of the palm's position
    alone (:func:`_shifted_palm`; 0: at ``q`` itself)."""

    def measure(model: KinematicModel, x: np.ndarray, jacobian: bool):
        kin = forward_kinematics(model, x)
        residuals, jacobians, n_valid = [], [], 0
        for camera, image in zip(rig, images, strict=True):
            measured = measure_features(image, camera, model, kin, features, link_names,
                                        tip_names)
            r, J, _ = feature_residuals(measured, camera, kin, jacobian=jacobian,
                                        axis_points=axis_points)
            residuals.append(r)
            jacobians.append(J)
            n_valid += measured.n_valid
        J = np.concatenate(jacobians) if jacobian else None
        return np.concatenate(residuals), J, n_valid

    def evaluate(model: KinematicModel) -> tuple[np.ndarray, int]:
        x = np.asarray(q, dtype=float)
        for _ in range(palm_iterations if model.base_state is not None else 0):
            x = _shifted_palm(model, x, q, rig, *measure(model, x, True)[:2])
        r, _, n_valid = measure(model, x, False)
        return r, n_valid

    return evaluate


CHECK_PALM_ITERATIONS = 3
"""A size other than the model file's is confirmed by measuring again with the palm's
position re-fitted at each size by this many Gauss-Newton steps: a start a few
millimetres off to the side makes some size fit the features at the start by chance, but
not once the palm has moved to where the image puts it (docs/features.md, "The hand's
size")."""


def _shifted_palm(model: KinematicModel, x: np.ndarray, q: np.ndarray, rig: Rig,
                  r: np.ndarray, J: np.ndarray) -> np.ndarray:
    """One Gauss-Newton step of the palm's position alone (rotation and fingers held)
    on the feature residuals ``r`` with their tangent Jacobian ``J`` at ``x``; with one
    camera the palm's distance along the optical axis stays that of the start ``q`` (one
    view cannot tell a larger hand further away, which is the size being measured)."""
    if len(r) == 0:
        return x
    k = model.base_state
    columns = model.q_to_v[k + 4:k + 7]
    A = J[:, columns]
    H, g = A.T @ A, A.T @ r
    if len(rig) == 1:
        axis = np.asarray(rig[0].T_cam_world, dtype=float)[2, :3]  # optical axis, world
        weight = 1e4 * max(float(np.trace(H)), 1.0)
        H = H + weight * np.outer(axis, axis)
        g = g + weight * axis * float(axis @ (x[k + 4:k + 7] - q[k + 4:k + 7]))
    step = np.linalg.solve(H + 1e-6 * max(float(np.trace(H)), 1.0) * np.eye(3), -g)
    out = np.array(x, dtype=float)
    out[k + 4:k + 7] += step
    return out


def start_size_costs(model: KinematicModel, evaluate: FeatureEvaluation, n_requested: int,
                     loss: RobustLoss | None, scale_px: float,
                     scales: np.ndarray = START_SCALES) -> np.ndarray:
    """The cost (module docstring) of the hand ``scale`` times the size of ``model`` for
    each of ``scales`` (S,): the robust cost (``loss``, ``scale_px``) of the residuals
    ``evaluate`` gives for :func:`~digiteyes.kinematics.scaling.scaled_model` of that
    size, plus :data:`INVALID_RESIDUAL_PX`'s cost for each of the ``n_requested``
    features it did not find."""
    invalid_cost = float(robust_cost(np.array([INVALID_RESIDUAL_PX]), loss, scale_px)[0])
    costs = np.empty(len(scales))
    for i, scale in enumerate(scales):
        residuals, n_valid = evaluate(scaled_model(model, float(scale), name=model.name))
        costs[i] = (float(robust_cost(residuals, loss, scale_px).sum())
                    + (n_requested - n_valid) * invalid_cost)
    return costs


def start_size(model: KinematicModel, evaluate: FeatureEvaluation, n_requested: int,
               loss: RobustLoss | None, scale_px: float) -> float:
    """The hand's size relative to ``model``: the one of :data:`START_SCALES` that explains
    the first frame's features best (:func:`start_size_costs`), refined to the vertex of
    the parabola through its neighbours, when it beats the model file's size by
    :data:`MIN_GAIN` and lies more than :data:`DEAD_BAND` from 1; else 1."""
    costs = start_size_costs(model, evaluate, n_requested, loss, scale_px)
    best = int(np.argmin(costs))
    at_one = float(costs[int(np.argmin(np.abs(START_SCALES - 1.0)))])
    size = _vertex(START_SCALES, costs, best)
    if not costs[best] <= (1.0 - MIN_GAIN) * at_one or abs(size - 1.0) <= DEAD_BAND:
        return 1.0
    return size


def hand_size_at(model: KinematicModel, rig: Rig, images: Sequence[np.ndarray], q: np.ndarray,
                 features: FeatureOptions | None = None,
                 link_names: Sequence[str] | None = None,
                 tip_names: Sequence[str] = (), axis_points: int = 2,
                 loss: RobustLoss | None = None, scale_px: float = 5.0) -> float:
    """The size of the hand in ``images`` (one per camera of ``rig``, grey or colour)
    relative to ``model``, measured at its known state ``q`` (n_q,; translation in mm)
    by :func:`start_size`, and a size other than 1 confirmed on the same side of 1 with
    the palm's position re-fitted (:data:`CHECK_PALM_ITERATIONS`; else 1): what every
    tracker with ``start_size`` calls on its first frame. ``link_names``/``tip_names``:
    the features to measure (None: the feature tracker's default set,
    :func:`~digiteyes.features.selection.feature_names`);
    ``features``, ``axis_points``, ``loss``, ``scale_px``: the feature tracker's settings
    (its defaults unless given)."""
    if link_names is None:
        link_names, tip_names = feature_names(model)
    prepared = [prepare_image(image).astype(np.float32, copy=False) for image in images]
    n_requested = (len(link_names) + len(tip_names)) * len(rig)
    sizes = []
    for palm_iterations in (0, CHECK_PALM_ITERATIONS):
        evaluate = feature_evaluation(rig, prepared, q, features or FeatureOptions(),
                                      link_names, tip_names, axis_points, palm_iterations)
        sizes.append(start_size(model, evaluate, n_requested, loss, scale_px))
        if sizes[0] == 1.0:
            return 1.0
    at_start, checked = sizes
    return at_start if (checked - 1.0) * (at_start - 1.0) > 0 else 1.0


class StartSize:
    """A tracker's hand size from its first frame (``start_size`` option): the model file's
    model, the size found (None: the tracker does not size the hand) and whether the
    coming first frame is still to be measured. The tracker rebuilds what depends on its
    model whenever :meth:`forget` or :meth:`measure` returns a model."""

    def __init__(self, model: KinematicModel, enabled: bool) -> None:
        self.nominal_model = model
        self.scale: float | None = 1.0 if enabled and model.base_state is not None else None
        self.pending = self.scale is not None

    @property
    def hand_scale(self) -> float:
        """The size results carry (:attr:`~digiteyes.trackers.TrackResult.hand_scale`)."""
        return 1.0 if self.scale is None else self.scale

    def forget(self) -> KinematicModel | None:
        """A new track: the size is unknown again. The model file's model when the tracker
        was on another size (to rebuild on), else None."""
        self.pending = self.scale is not None
        if self.scale is None or self.scale == 1.0:
            return None
        self.scale = 1.0
        return self.nominal_model

    def measure(self, rig: Rig, images: Sequence[np.ndarray], q: np.ndarray,
                **settings) -> KinematicModel | None:
        """On the first frame of a track (else None): the size at the start state ``q``
        (:func:`hand_size_at`, ``settings`` passed on); the model of that size when it is
        not the current one (to rebuild on), else None."""
        if not self.pending:
            return None
        self.pending = False
        scale = hand_size_at(self.nominal_model, rig, images, q, **settings)
        if scale == self.scale:
            return None
        self.scale = scale
        return scaled_model(self.nominal_model, scale, name=self.nominal_model.name)


def _vertex(scales: np.ndarray, costs: np.ndarray, best: int) -> float:
    """The minimum of the parabola through the grid's least cost ``best`` and its two
    neighbours (within half a grid step of ``scales[best]``; the grid point itself at
    either end of the grid or where the three do not curve upwards)."""
    if not 0 < best < len(scales) - 1:
        return float(scales[best])
    left, middle, right = costs[best - 1], costs[best], costs[best + 1]
    curvature = left - 2.0 * middle + right
    if not curvature > 0 or not np.isfinite(curvature):
        return float(scales[best])
    step = float(scales[best + 1] - scales[best])
    offset = float(np.clip(0.5 * (left - right) / curvature, -0.5, 0.5))
    return float(scales[best]) + offset * step


__all__ = [
    "CHECK_PALM_ITERATIONS",
    "DEAD_BAND",
    "INVALID_RESIDUAL_PX",
    "MIN_GAIN",
    "START_SCALES",
    "FeatureEvaluation",
    "StartSize",
    "feature_evaluation",
    "hand_size_at",
    "start_size",
    "start_size_costs",
]
