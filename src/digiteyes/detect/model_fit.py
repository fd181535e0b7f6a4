"""The kinematic hand model fitted to detected keypoints: a full state in millimetres.

The fit minimises, over the state ``q`` of the nominal model and a global hand scale
``s`` (the posed points are ``s * p_k(q)``, :func:`~digiteyes.kinematics.scaling.scaled_model`),

``E(q, s) = sum_c sum_k rho(c_k |pi_c(s p_k(q)) - u_ck|^2 / sigma_px^2)``   (2D, per camera)
``        + sum_k rho(|s p_k(q) - y_k|^2 / sigma_mm^2)``                  (3D, when given)
``        + sum_c sum_k |R_c s (p_k - p_bar) - z (y_ck - y_bar_c)|^2 / sigma_shape^2``
                                                            (a detector's 3D shape, when given)
``        + sum_j ((theta_j - mu_j) / sigma_theta)^2 + ((s - s0) / sigma_s)^2``   (prior)

with ``rho`` Huber's loss (one sigma), joint limits enforced by projection after every
step, and Levenberg-Marquardt steps (thesis eq. 2.22 with adaptive damping). The
Jacobian chains the camera's projection Jacobian with the point Jacobian of the tree
(thesis eq. 2.16 / report eq. 8-10): ``d pi / d v = J_pi (s J_p)`` and
``d pi / d s = J_pi p``.

**Metric scale.** With one camera the image constrains ``s`` only through the prior: a
hand ``s`` times larger at ``s`` times the depth projects to the same pixels. The scale is
then held at ``s0`` (the nominal hand, or the user's calibrated hand), and the depth
error is the hand-size error: a hand 10 % larger than assumed is placed 10 % too far.
With 3D keypoints or two or more cameras ``s`` is fitted.

**A detector's own 3D shape.** MediaPipe also estimates metric 3D keypoints (its "world
landmarks": camera axes, origin near the hand's centre, an average hand's size). When a
:class:`KeypointObservation` carries them (``shape_3d``), the fit also matches the
hand's shape to them, translation-free: both point sets about their centroids, ``R_c``
the camera's rotation, and ``z`` the ratio of the summed bone lengths of the model (at
``s0``) and of the detector's points, so that the term compares shapes, not sizes. It
constrains what one view leaves open (a finger bent towards or away from the camera).
The term is used when ``FitOptions.sigma_shape_mm`` is set (off by default: measured on
real images it helps as often as it harms, docs/initialisation.md).

The start comes from the palm: the wrist and the four MCP joints are coplanar and fixed
in the palm frame, so a planar pose (OpenCV's IPPE, both of its solutions) places the
palm in a camera; 3D targets use :func:`~digiteyes.kinematics.procrustes.kabsch`. The
fit scouts from each start (a few iterations with the fingers extended and curled, the
better joints kept digit by digit) and refines the start of lowest cost.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache

import cv2
import numpy as np

from digiteyes.camera import Camera
from digiteyes.camera.camera import PROJECTION_PARAMS
from digiteyes.detect._fit_kernels import keypoint_terms_kernel
from digiteyes.detect.candidate import HandCandidate
from digiteyes.detect.hand21 import (
    BONES,
    DIGIT_KEYPOINTS,
    DIGITS,
    HAND21_NAMES,
    PALM,
    PALM_FIXED,
    model_anchors,
)
from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import (
    KinematicModel,
    clip_to_limits,
    difference,
    forward_kinematics,
    held_at_limits,
    integrate,
)
from digiteyes.kinematics.forward import fk_tables
from digiteyes.kinematics.jacobian import jacobian_tables
from digiteyes.kinematics.procrustes import kabsch
from digiteyes.kinematics.rotations import quaternion_from_matrix
from digiteyes.solvers import GaussNewtonOptions, gauss_newton, robust_cost

SCOUT_ITERATIONS = 3
"""Iterations of each scouting fit (extended and curled fingers) before the refinement."""


@dataclass(frozen=True)
class FitOptions:
    """Settings of :func:`fit_keypoints`.

    Attributes
    ----------
    sigma_px : expected keypoint error of the detector, px (the Huber scale of 2D terms).
    sigma_mm : expected error of 3D keypoints, mm.
    sigma_shape_mm : expected error of a detector's 3D shape (``shape_3d``), mm; None (the
        default) leaves the shape out. Off by default because on the real images we have
        it helps as often as it harms (docs/initialisation.md, "A detector's 3D shape").
    sigma_joint_deg : width of the prior on each joint angle about ``prior_mean`` (deg).
    scale : assumed hand scale ``s0`` (1 = the model file's hand).
    sigma_scale : width of the prior on the scale when it is fitted.
    fit_scale : ``None`` fits the scale exactly when it is observable (3D targets or two
        or more cameras); True or False forces it.
    iterations : Levenberg-Marquardt iterations at most in the refinement.
    motion_sigma : with a start state ``q0``, a prior on the step from it: ``(mm, deg)``,
        the expected change of the palm's position (mm) and of every angle, the palm's
        rotation included (deg), e.g. per frame of a track (the stabilisation of
        Rehg's eq. 2.22 as a prior); None (default): no such prior.
    hold_position_mm : with a start state ``q0``, a prior that holds the palm's position
        in millimetres (``s`` times the state's translation, the scale included) to
        ``q0``'s (at ``scale``) within this sigma: with the scale fitted, the hand's
        size is then what its image size is at the start's depth (the keypoint
        tracker's size at the start); None (default): no such prior.
    active_set : hold, in each step, the joints that sit at a limit the cost pushes beyond
        (:func:`~digiteyes.kinematics.held_at_limits`, docs/solvers.md): the fit then
        converges where a joint is at its limit, instead of creeping by rejected,
        clipped steps. On in the keypoint tracker's fits; off (default) for the fits
        from the images alone (the start, ``pose``), where it was not measured better
        (docs/keypoint-tracker.md, "A fit that converges").
    """

    sigma_px: float = 4.0
    sigma_mm: float = 5.0
    sigma_shape_mm: float | None = None
    sigma_joint_deg: float = 45.0
    scale: float = 1.0
    sigma_scale: float = 0.15
    fit_scale: bool | None = None
    iterations: int = 10
    motion_sigma: tuple[float, float] | None = None
    hold_position_mm: float | None = None
    active_set: bool = False


@dataclass
class KeypointObservation:
    """Detected keypoints in one camera: (21, 2) px and (21,) confidences in [0, 1];
    optionally the detector's own 3D shape ``shape_3d`` (21, 3) mm in the camera's axes,
    origin anywhere (module docstring)."""

    camera: Camera
    keypoints: np.ndarray
    confidence: np.ndarray = field(default_factory=lambda: np.ones(21))
    shape_3d: np.ndarray | None = None

    @classmethod
    def of(cls, candidate: HandCandidate, camera: Camera) -> KeypointObservation:
        """The observation of a detector's candidate in ``camera``: its keypoints,
        confidences and, when it has them, its 3D keypoints as the shape."""
        return cls(camera, candidate.keypoints, candidate.keypoint_confidence,
                   candidate.keypoints_3d)


@dataclass
class PoseFit:
    """A fitted hand.

    Attributes
    ----------
    model : the nominal model the state belongs to.
    q : state (n_q,) of ``model``; its base translation is in *model* units, so the posed
        points are ``scale * p(q)`` (see :meth:`scaled_state`).
    scale : fitted or assumed hand scale (dimensionless).
    keypoints_world : (21, 3) mm in the world frame of the cameras.
    reprojection_px : (n_cameras, 21) distance from each detected keypoint, px.
    cost : final cost (robust, dimensionless).
    iterations : solver iterations of the chosen start.
    scale_fitted : whether ``scale`` was estimated (False: assumed).
    """

    model: KinematicModel
    q: np.ndarray
    scale: float
    keypoints_world: np.ndarray
    reprojection_px: np.ndarray
    cost: float
    iterations: int
    scale_fitted: bool

    def scaled_state(self) -> np.ndarray:
        """The state of ``scaled_model(model, scale)`` that poses the same hand (mm)."""
        q = np.array(self.q)
        k = self.model.base_state
        q[k + 4:k + 7] *= self.scale
        return q

    def keypoints_camera(self, camera: Camera) -> np.ndarray:
        """The 21 keypoints in ``camera``'s frame (21, 3), mm."""
        return camera.to_camera(self.keypoints_world)

    def joint_angles_deg(self) -> dict[str, float]:
        """Every angle state by name, degrees."""
        return {spec.name: float(np.degrees(self.q[spec.index]))
                for spec in self.model.spec.states if spec.kind == "angle"}


class KeypointFitProblem:
    """The cost of :mod:`this module <digiteyes.detect.model_fit>` as a
    :class:`~digiteyes.solvers.LeastSquaresProblem` over ``x = (q, s)``; residuals are in
    units of their sigma."""

    def __init__(self, model: KinematicModel, observations: Sequence[KeypointObservation],
                 target_3d: np.ndarray | None, options: FitOptions, fit_scale: bool,
                 prior_mean: np.ndarray | None = None,
                 target_weights: np.ndarray | None = None,
                 motion_from: np.ndarray | None = None) -> None:
        self.model = model
        self.observations = list(observations)
        self.target_3d = None if target_3d is None else np.asarray(target_3d, dtype=float)
        self._weights_3d = np.ones(21) if target_weights is None else np.sqrt(
            np.clip(np.asarray(target_weights, dtype=float), 0.0, 1.0))
        if self.target_3d is not None:  # a missing 3D point (NaN) carries no weight
            missing = ~np.isfinite(self.target_3d).all(axis=1)
            self._weights_3d = np.where(missing, 0.0, self._weights_3d)
            self.target_3d = np.where(missing[:, None], 0.0, self.target_3d)
        self.options = options
        self.fit_scale = fit_scale
        rows, points = model_anchors(model)
        self.rows = np.ascontiguousarray(rows, dtype=np.int64)
        self.points = np.ascontiguousarray(points, dtype=float)
        self.angle_states = np.array([s.index for s in model.spec.states if s.kind == "angle"])
        self.angle_columns = model.q_to_v[self.angle_states]
        self.prior_mean = (model.neutral() if prior_mean is None else prior_mean)[
            self.angle_states]
        self.n_v = model.n_v + 1
        self._weights = [np.sqrt(np.clip(o.confidence, 0.0, 1.0)) / options.sigma_px
                         for o in self.observations]
        self._shapes = [self._shape_target(o) for o in self.observations]
        # the 2D terms' inputs for the compiled kernel (:mod:`~digiteyes.detect._fit_kernels`)
        n_cameras = len(self.observations)
        self._cameras = np.zeros((n_cameras, PROJECTION_PARAMS))
        self._keypoints = np.zeros((n_cameras, 21, 2))
        self._keypoint_weights = np.zeros((n_cameras, 21))
        for c, (obs, w) in enumerate(zip(self.observations, self._weights, strict=True)):
            self._cameras[c] = obs.camera.projection_params
            self._keypoints[c] = obs.keypoints
            self._keypoint_weights[c] = w
        self._fk_tables = fk_tables(model)
        self._jac_tables = jacobian_tables(model, "tangent")
        self.motion_from = None
        if motion_from is not None and options.motion_sigma is not None:
            self.motion_from = np.asarray(motion_from, dtype=float)
            self._motion_weights = 1.0 / _motion_sigmas(model, *options.motion_sigma)
        self.position_from = None
        if motion_from is not None and options.hold_position_mm is not None:
            k = model.base_state
            self.position_from = options.scale * np.asarray(motion_from, dtype=float)[k + 4:k + 7]
            self._position_columns = model.q_to_v[k + 4:k + 7]
        # the Jacobians of the priors on the joint angles, the step and the scale: constant
        n = model.n_v
        self._sigma_joint = np.radians(options.sigma_joint_deg)
        self._joint_jacobian = np.zeros((len(self.angle_states), n + 1))
        self._joint_jacobian[np.arange(len(self.angle_states)), self.angle_columns] = \
            1.0 / self._sigma_joint
        if self.motion_from is not None:
            # the step from the start, in tangent coordinates; its Jacobian with respect to
            # a step is the identity up to the rotation's second-order terms
            self._motion_jacobian = np.zeros((n, n + 1))
            self._motion_jacobian[np.arange(n), np.arange(n)] = self._motion_weights
        self._scale_jacobian = np.zeros((1, n + 1))
        self._scale_jacobian[0, n] = 1.0 / options.sigma_scale

    def _shape_target(self, obs: KeypointObservation) -> np.ndarray | None:
        """The detector's shape of ``obs`` about its centroid, brought to the size of the
        model at the assumed scale (ratio of summed bone lengths); None without one."""
        if obs.shape_3d is None or self.options.sigma_shape_mm is None:
            return None
        y = np.asarray(obs.shape_3d, dtype=float)
        if y.shape != (21, 3) or not np.isfinite(y).all():
            return None
        p = forward_kinematics(self.model, self.model.neutral()).points(self.rows, self.points)
        bones = np.array(BONES)
        length = np.linalg.norm(y[bones[:, 0]] - y[bones[:, 1]], axis=1).sum()
        model_length = self.options.scale * np.linalg.norm(
            p[bones[:, 0]] - p[bones[:, 1]], axis=1).sum()
        if not length > 0:
            return None
        return (y - y.mean(axis=0)) * (model_length / length)

    def residuals(self, x: np.ndarray, jacobian: bool) -> tuple[np.ndarray, np.ndarray | None]:
        q, s = x[:-1], float(x[-1])
        n = self.model.n_v
        n_2d = 42 * len(self.observations)
        r_2d = np.empty(n_2d)
        J_2d = np.empty((n_2d if jacobian else 0, n + 1))
        p_world = np.empty((1, 21, 3))
        Jp = np.empty((1, 21, 3, n))
        keypoint_terms_kernel(np.ascontiguousarray(q, dtype=float).reshape(1, -1),
                              self._fk_tables, self._jac_tables, self.rows, self.points,
                              self._cameras, self._keypoints, self._keypoint_weights, s,
                              jacobian, np.empty((1, self.model.n_frames, 4, 4)), p_world,
                              Jp, r_2d, J_2d)
        p, Jp = p_world[0], Jp[0]
        parts, jac = [r_2d], [J_2d]
        for obs, shape in zip(self.observations, self._shapes, strict=True):
            if shape is None:
                continue
            R = obs.camera.T_cam_world[:3, :3]
            centred = p - p.mean(axis=0)
            parts.append(((s * centred @ R.T - shape) / self.options.sigma_shape_mm).ravel())
            if jacobian:
                block = np.empty((21, 3, n + 1))
                block[..., :n] = s * (R @ (Jp - Jp.mean(axis=0)))
                block[..., n] = centred @ R.T
                jac.append((block / self.options.sigma_shape_mm).reshape(63, n + 1))
        if self.target_3d is not None:
            sigma = self.options.sigma_mm
            w3 = self._weights_3d[:, None] / sigma
            parts.append(((s * p - self.target_3d) * w3).ravel())
            if jacobian:
                block = np.concatenate([s * Jp, p[..., None]], axis=2) * w3[..., None]
                jac.append(block.reshape(63, n + 1))
        parts.append((q[self.angle_states] - self.prior_mean) / self._sigma_joint)
        if jacobian:
            jac.append(self._joint_jacobian)
        if self.motion_from is not None:
            parts.append(difference(self.model, self.motion_from, q) * self._motion_weights)
            if jacobian:
                jac.append(self._motion_jacobian)
        if self.position_from is not None:
            # the palm's position in mm, s t: d/d(step) = s I on the translation
            # columns (translation steps add), d/ds = t
            k = self.model.base_state
            sigma = self.options.hold_position_mm
            t = q[k + 4:k + 7]
            parts.append((s * t - self.position_from) / sigma)
            if jacobian:
                block = np.zeros((3, n + 1))
                block[np.arange(3), self._position_columns] = s / sigma
                block[:, n] = t / sigma
                jac.append(block)
        parts.append(np.array([(s - self.options.scale) / self.options.sigma_scale]))
        if jacobian:
            jac.append(self._scale_jacobian)
        r = np.concatenate(parts)
        if not jacobian:
            return r, None
        J = np.concatenate(jac)
        if not self.fit_scale:
            J[:, n] = 0.0
        return r, J

    def keypoint_errors(self, x: np.ndarray) -> np.ndarray:
        """Per keypoint (21,): squared weighted 2D and 3D residuals summed over cameras."""
        r, _ = self.residuals(x, False)
        n_2d = 42 * len(self.observations)
        errors = (r[:n_2d].reshape(-1, 21, 2) ** 2).sum(axis=(0, 2))
        n_3d = 63 * (sum(shape is not None for shape in self._shapes)
                     + (self.target_3d is not None))
        if n_3d:
            errors = errors + (r[n_2d:n_2d + n_3d].reshape(-1, 21, 3) ** 2).sum(axis=(0, 2))
        return errors

    def retract(self, x: np.ndarray, dv: np.ndarray) -> np.ndarray:
        s = x[-1] + (dv[-1] if self.fit_scale else 0.0)
        return _with_scale(integrate(self.model, x[:-1], dv[:-1]), s)

    def project(self, x: np.ndarray) -> np.ndarray:
        return _with_scale(clip_to_limits(self.model, x[:-1]), min(max(x[-1], 0.5), 2.0))

    def held(self, x: np.ndarray, gradient: np.ndarray) -> np.ndarray:
        """With ``options.active_set``, the joints at a limit that the cost pushes beyond
        (the scale is never held: its bounds are far from any hand); else none."""
        if not self.options.active_set:
            return np.zeros(len(gradient), dtype=bool)
        return np.append(held_at_limits(self.model, x[:-1], gradient[:-1]), False)


def _with_scale(q: np.ndarray, s: float) -> np.ndarray:
    """The fit's parameters ``x = (q, s)`` (``np.append``'s result, without its cost at
    every solver step)."""
    x = np.empty(len(q) + 1)
    x[:-1] = q
    x[-1] = s
    return x


def _motion_sigmas(model: KinematicModel, sigma_mm: float, sigma_deg: float) -> np.ndarray:
    """Per tangent component of ``model`` (n_v,): ``sigma_mm`` for the base translation,
    ``sigma_deg`` (in radians) for the base rotation and every angle."""
    sigmas = np.full(model.n_v, np.radians(sigma_deg))
    for spec in model.spec.states:
        if spec.kind == "trans":
            sigmas[model.q_to_v[spec.index]] = sigma_mm
    return sigmas


def palm_points(model: KinematicModel, q: np.ndarray | None = None) -> np.ndarray:
    """The 21 keypoints (21, 3) mm in the palm frame at the joint angles of ``q`` (its base
    pose ignored; default: the neutral joint angles)."""
    q = model.neutral() if q is None else np.array(q, dtype=float)
    k = model.base_state
    q[k:k + 7] = model.neutral()[k:k + 7]
    rows, points = model_anchors(model)
    return forward_kinematics(model, q).points(rows, points)


def _state_from_pose(model: KinematicModel, R: np.ndarray, t: np.ndarray, scale: float,
                     joints: np.ndarray) -> np.ndarray:
    q = np.array(joints, dtype=float)
    k = model.base_state
    q[k:k + 4] = quaternion_from_matrix(R)
    q[k + 4:k + 7] = t / scale
    return q


def starts_from_3d(model: KinematicModel, target: np.ndarray, scale: float) -> list[np.ndarray]:
    """One start: the palm-fixed keypoints of the model (scaled) aligned to ``target``."""
    keys = [k for k in PALM_FIXED if np.isfinite(target[k]).all()]
    if len(keys) < 3:
        raise DigitEyesError("model fit: at least three of the wrist, thumb CMC and MCP 3D "
                             "points are needed to place the palm")
    palm = scale * palm_points(model)[keys]
    R, t, _ = kabsch(palm, np.asarray(target)[keys])
    return [_state_from_pose(model, R, t, scale, model.neutral())]


def starts_from_image(model: KinematicModel, obs: KeypointObservation,
                      scale: float) -> list[np.ndarray]:
    """Starts from the palm's planar pose in one camera (both IPPE solutions), in world;
    when neither puts the palm in front of the camera (a palm seen nearly edge-on, whose
    detected keypoints no planar palm of the model's shape matches well), the general
    PnP solution (SQPnP) instead."""
    palm = scale * palm_points(model)[list(PALM)]
    image = np.asarray(obs.keypoints, dtype=float)[list(PALM)]
    if not np.isfinite(image).all():
        raise DigitEyesError("model fit: the wrist and the four MCP keypoints are needed to "
                             "place the palm")
    cam = obs.camera
    try:
        count, rvecs, tvecs, _ = cv2.solvePnPGeneric(
            palm.astype(np.float64), image.astype(np.float64), np.asarray(cam.K),
            np.asarray(cam.dist), flags=cv2.SOLVEPNP_IPPE)
    except cv2.error as exc:
        raise DigitEyesError(f"model fit: palm pose failed ({exc.err})") from None
    poses = list(zip(rvecs[:count], tvecs[:count], strict=True))
    if not any(np.ravel(tvec)[2] > 0 for _, tvec in poses):
        try:
            found, rvec, tvec = cv2.solvePnP(palm.astype(np.float64),
                                             image.astype(np.float64), np.asarray(cam.K),
                                             np.asarray(cam.dist), flags=cv2.SOLVEPNP_SQPNP)
        except cv2.error:  # degenerate keypoints (e.g. all on one pixel)
            found = False
        poses = [(rvec, tvec)] if found else []
    starts = []
    T_world_cam = cam.T_world_cam
    for rvec, tvec in poses:
        T = np.eye(4)
        T[:3, :3] = cv2.Rodrigues(rvec)[0]
        T[:3, 3] = np.ravel(tvec)
        if not np.isfinite(T).all() or T[2, 3] <= 0:
            continue
        T_world_palm = T_world_cam @ T
        starts.append(_state_from_pose(model, T_world_palm[:3, :3], T_world_palm[:3, 3],
                                       scale, model.neutral()))
    if not starts:
        raise DigitEyesError("model fit: no palm pose in front of the camera fits the keypoints")
    return starts


CURLED_START_DEG = 40.0
"""Flexion of every finger joint (MCP, PIP, DIP) in the curled start, degrees."""


def _curled(model: KinematicModel, q: np.ndarray) -> np.ndarray:
    """``q`` with the finger flexions at :data:`CURLED_START_DEG` (thumb unchanged)."""
    q = np.array(q)
    for digit in DIGITS[1:]:
        for joint in ("mcp", "pip", "dip"):
            q[model.state_index(f"{digit}.{joint}")] = np.radians(CURLED_START_DEG)
    return clip_to_limits(model, q)


@lru_cache(maxsize=16)
def _digit_states(model: KinematicModel) -> dict[str, list[int]]:
    return {d: [s.index for s in model.spec.states if s.name.startswith(f"{d}.")]
            for d in DIGITS}


def _solver_options(iterations: int) -> GaussNewtonOptions:
    return GaussNewtonOptions(max_iterations=iterations, damping="levenberg-marquardt",
                              robust_loss="huber", scale_px=1.0, step_tolerance=1e-6,
                              cost_tolerance=1e-7)


def _scout(problem: KeypointFitProblem, x0: np.ndarray) -> tuple[np.ndarray, float]:
    """A few iterations from the extended and from the curled fingers, then digit by
    digit the joints whose keypoints fit better (a finger seen from the front can bend
    towards or away from the camera; the digits are independent given the palm). Returns
    the combined parameters and their cost."""
    model = problem.model
    short = _solver_options(SCOUT_ITERATIONS)
    scouts = [gauss_newton(problem, x0, short)[0],
              gauss_newton(problem, np.append(_curled(model, x0[:-1]), x0[-1]), short)[0]]
    errors = [problem.keypoint_errors(x) for x in scouts]
    x = np.array(scouts[0])
    for digit, states in _digit_states(model).items():
        keys = DIGIT_KEYPOINTS[digit]
        if errors[1][keys].sum() < errors[0][keys].sum():
            x[states] = scouts[1][states]
    r, _ = problem.residuals(x, False)
    return x, float(robust_cost(r, "huber", 1.0).sum())


def fit_keypoints(model: KinematicModel, observations: Sequence[KeypointObservation] = (),
                  target_3d: np.ndarray | None = None,
                  options: FitOptions = FitOptions(),
                  q0: np.ndarray | None = None) -> PoseFit:
    """Fit ``model`` to 2D keypoints in any number of cameras and/or 3D keypoints (mm).

    Parameters
    ----------
    model : the hand model (the 21 keypoints of :mod:`~digiteyes.detect.hand21`).
    observations : detected keypoints per camera (world frame of the cameras).
    target_3d : (21, 3) world mm, or None; rows of NaN are missing points.
    options : :class:`FitOptions`.
    q0 : a start state of ``model`` (translation in model units); None starts from the
        palm pose.

    Raises :class:`DigitEyesError` when there is nothing to fit.
    """
    observations = list(observations)
    if not observations and target_3d is None:
        raise DigitEyesError("model fit: give keypoints in at least one camera or 3D keypoints")
    fit_scale = options.fit_scale
    if fit_scale is None:
        fit_scale = target_3d is not None or len(observations) >= 2
    problem = KeypointFitProblem(model, observations, target_3d, options, fit_scale,
                                 motion_from=q0)
    if q0 is not None:
        starts = [np.asarray(q0, dtype=float)]
    elif target_3d is not None:
        starts = starts_from_3d(model, target_3d, options.scale)
    else:
        best = max(observations, key=lambda o: float(np.sum(o.confidence)))
        starts = starts_from_image(model, best, options.scale)
    full = _solver_options(options.iterations)
    if q0 is not None:
        best_x, best_summary = gauss_newton(problem, np.append(starts[0], options.scale), full)
    else:  # scout every palm start, refine the best
        scouted = [_scout(problem, np.append(q, options.scale)) for q in starts]
        x_start = min(scouted, key=lambda pair: pair[1])[0]
        best_x, best_summary = gauss_newton(problem, x_start, full)
    q, s = best_x[:-1], float(best_x[-1])
    rows, points = problem.rows, problem.points
    world = s * forward_kinematics(model, q).points(rows, points)
    reproj = np.array([np.linalg.norm(o.camera.project(world) - o.keypoints, axis=1)
                       for o in observations]).reshape(len(observations), 21)
    return PoseFit(model, q, s, world, reproj, float(best_summary.cost_final),
                   best_summary.iterations, bool(fit_scale))


__all__ = ["HAND21_NAMES", "FitOptions", "KeypointFitProblem", "KeypointObservation",
           "PoseFit", "fit_keypoints", "palm_points", "starts_from_3d", "starts_from_image"]
