"""The DigitEyes feature tracker (thesis Sec. 2.5 and 4.3.2, report Sec. 5).

Per frame: predict the state from the past estimates, then run a few stabilised
Gauss-Newton iterations (thesis eq. 2.22). Every residual evaluation is one pass of the
thesis's loop (Sec. 4.3.2 steps 1-5): forward kinematics at the current iterate, feature
search around the projected model in every camera, line and tip residuals with their
Jacobians, stacked over the cameras into one system (thesis Sec. 2.5.5). The solve and the
state update are steps 6-7. Finally the track-loss rules look at the result.

Track loss (thesis Sec. 4.1, 4.3.2: the search windows no longer contain the features):
a frame is flagged ``lost`` when

* no feature could be measured at all;
* more than ``max_invalid_fraction`` of the requested features are invalid, and more
  than in the first frame (at the true initial state) by over ``invalid_margin`` (a hand
  that looks unlike the model, thinner or tapered fingers, fails the width check on many
  features even where the pose is right);
* the residual RMS exceeds ``max_residual_rms_px`` (default: half the feature window,
  where the features start falling out of their windows);
* the residual RMS has grown in each of the last ``growth_frames`` frames to more than
  ``growth_factor`` times its value before them (and above ``growth_min_px``);
* (``silhouette_check``, a plain backdrop) the model drawn at the estimate leaves more
  than ``max_unexplained`` of its own area of the hand's silhouette unexplained, beyond
  what it left at the true first state, or puts more than ``max_finger_outside`` of a
  finger over the backdrop beyond that finger's share at the first state (that finger
  is flagged in ``finger_lost``; :mod:`digiteyes.trackers.silhouette_loss`, shared
  with the other trackers). The feature residual alone cannot see a
  finger that has snapped onto its neighbour's edges: each measured edge is then close
  to some predicted line (docs/accuracy.md).

A lost frame is reported, not acted on: tracking continues from the estimate, and the
constant-velocity prediction drops its velocity.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from digiteyes.camera import Rig
from digiteyes.errors import StateError
from digiteyes.features import FeatureOptions, feature_residuals, measure_features
from digiteyes.features.appearance import EdgeBias, ShadingModel, edge_bias, fit_shading
from digiteyes.features.edge_signs import learn_side_signs
from digiteyes.features.selection import feature_names
from digiteyes.features.slices import prepare_image
from digiteyes.features.width_scale import link_radius_scales
from digiteyes.kinematics import (
    STEP_FORMS,
    KinematicModel,
    Kinematics,
    StepForm,
    forward_kinematics,
    validate_state,
)
from digiteyes.solvers import (
    GaussNewtonOptions,
    SolverSummary,
    gauss_newton,
    hand_conditioning,
)
from digiteyes.solvers.options import DAMPINGS, Damping
from digiteyes.solvers.robust import ROBUST_LOSSES, RobustLoss
from digiteyes.trackers.base import TrackResult, start_step
from digiteyes.trackers.feature_size import StartSize, hand_size_at
from digiteyes.trackers.finger_search import FingerRecovery, FingerSearchOptions
from digiteyes.trackers.loss_hold import LossHold, LossHoldOptions
from digiteyes.trackers.parameterisation import StateParameterisation
from digiteyes.trackers.prediction import PREDICTIONS, PredictionKind, StatePredictor
from digiteyes.trackers.silhouette_loss import (
    SilhouetteLoss,
    SilhouetteLossOptions,
    SilhouetteVerdict,
)

NO_FEATURES = "no features measured"
"""The loss reason of a frame without any valid feature (given alone)."""
@dataclass(frozen=True)
class FeatureTrackerOptions(SilhouetteLossOptions, LossHoldOptions, FingerSearchOptions):
    """Settings of :class:`FeatureTracker` (defaults follow thesis Table 4.2).

    Attributes
    ----------
    iterations_per_frame : Gauss-Newton iterations per frame; each re-measures the
        features at the current iterate.
    features : feature-search settings (window size, slices, contrast).
    links : names of the cylinder links, edges and tips to measure; ``None`` for the
        default set: every one but :data:`THESIS_EXCLUDED_LINKS`. :func:`all_features`
        gives every one, :func:`thesis_whole_hand_links` the thesis's whole-hand set
        (no palm edges).
    axis_points : residual points per link along its axis (2: base and end; 1: base only,
        as the thesis, Sec. 4.3.1).
    width_weight : weight of the link-width residuals, the depth cue that one camera
        otherwise lacks (:mod:`digiteyes.features.residuals`; docs/features.md). 0 gives
        the thesis's residuals only.
    max_width_error : width rows whose measured width is off the predicted one by more
        than this fraction are left out.
    fit_widths : with one camera, measure each link's width and scale its radius in the
        width residuals to match (:mod:`digiteyes.features.width_scale`: the user's
        fingers, not the model's): at the start state on the first frame when the start
        fits the image, else (an automatic start, centimetres off) at the solved state of
        the first frame not flagged lost whose state fits it (the model's radii until
        then); kept through a :meth:`FeatureTracker.restart`. Several cameras see depth
        by themselves, and there the fitted widths made the track worse
        (docs/features.md, "Width calibration").
    learn_edge_signs : on the first frame of a track, in a camera where the hand's darkest
        pixels reach the backdrop's grey levels (a grey wall, a dark hand), let each link
        side search for edges of the sign its silhouette shows at the start state
        (:mod:`digiteyes.features.edge_signs`); kept through a
        :meth:`FeatureTracker.restart`. Elsewhere (black cloth) nothing changes. On by
        default since the seventeenth session: on renders over a grey wall and of a dark
        hand it halves the feature tracker's error; on the real video it tracks as well
        between re-detections and needs a fifth fewer of them (docs/accuracy.md,
        "Renders the trackers were not developed on").
    start_size : on the first frame of a track, measure the hand's size at the start
        state from its features and track a model of that size
        (:mod:`digiteyes.trackers.feature_size`; models with a pose base). The start must
        be the hand's pose (a dataset's state): ``digiteyes track`` turns it off for a
        start fitted from the images or placed by eye on footage. Kept through a
        :meth:`FeatureTracker.restart`; results carry the size as
        :attr:`~digiteyes.trackers.TrackResult.hand_scale`.
    conditioning : weights of ``S`` for (quaternion/rotation, translation, joint angle),
        thesis eq. 2.22 and Table 4.2: 1, 10, 1000 (px^2 per squared step unit).
    use_conditioning : False drops ``S`` (plain Gauss-Newton; an ablation).
    shading_correction : predict the image of the model under a shading model fitted on
        the first frame, search it for features too and subtract the residuals found
        there (:mod:`digiteyes.features.appearance`): removes the inward pull of skin
        shading on the measured edges. False gives the plain feature residuals.
    shading_every : frames between two predictions of the shading bias (1: every frame).
    blur_sigma_px : optical blur of the cameras in the shading prediction, px.
    static_backdrop : the cameras do not move, so the prediction may draw the model over
        the backdrop they saw around it in the first frame; False draws it over a uniform
        backdrop of the level seen around the model.
    max_backdrop_texture : no shading correction when the backdrop around the model in
        the first frame has more texture than this (RMS grey levels,
        :attr:`~digiteyes.features.appearance.ShadingModel.backdrop_texture`): in clutter
        the backdrop's own edges, not the shading, dominate the feature errors, and a
        prediction that measures them where they were makes the track worse
        (docs/features.md).
    damping : ``"fixed"`` (thesis) or ``"levenberg-marquardt"``.
    robust_loss : ``None``, ``"huber"`` or ``"tukey"`` on the feature residuals.
    robust_scale_px : scale of the robust loss, pixels.
    clip_to_limits : clip joint states into their limits after every step.
    prediction : ``"none"`` (start from the previous estimate, as the thesis; the default,
        because extrapolating amplifies drift along weakly observed directions, see
        docs/tracker.md) or ``"constant-velocity"`` (tangent-space extrapolation, which
        helps on fast motion).
    form : the :class:`~digiteyes.kinematics.StepForm`: tangent steps (n_v) or the
        thesis's quaternion form (n_q); the spellings ``"tangent"``/``"quaternion"`` are
        accepted and turned into the object.
    max_invalid_fraction : lost when more than this fraction of requested features is
        invalid (and more than ``invalid_margin`` above the first frame's fraction).
    invalid_margin : see ``max_invalid_fraction``.
    max_residual_rms_px : lost when the final residual RMS exceeds this; ``None`` means
        half the feature window (``features.window_px / 2``).
    growth_frames, growth_factor, growth_min_px : lost when the residual RMS rose in each
        of the last ``growth_frames`` frames, to more than ``growth_factor`` times its value
        before them and above ``growth_min_px``.
    silhouette_check : compare the model's silhouette at the estimate with the hand's
        (a grey threshold fitted on the first frame; off over a textured backdrop).
    silhouette_tolerance_px : differences of the two silhouettes within this distance are
        ignored, px.
    max_unexplained : lost when the hand pixels beyond the tolerance of the model, per
        model pixel, exceed their first-frame value by more than this.
    max_finger_outside : a finger is lost when the fraction of its model pixels beyond the
        tolerance of the hand's silhouette exceeds its first-frame value by more than
        this.
    hold_lost_frames : after a frame the loss rules call lost, later frames stay lost
        until this many in a row have passed them
        (:class:`~digiteyes.trackers.loss_hold.LossHold`; 0, the default, judges each
        frame alone).
    finger_search, finger_search_levels, finger_search_margin : on a frame the silhouette
        rule calls lost, search each digit's curl by the silhouette and solve again from
        the result (:mod:`digiteyes.trackers.finger_search`; off by default).
    hidden_finger_search : search only the digits the rule's hidden-digit test names, on
        the frames it names them (off by default).
    named_finger_search : search the digits the rule flags or names hidden (with
        ``judge_curled_digits``, also curled) while the image shows them open (off by
        default; :class:`~digiteyes.trackers.finger_search.FingerSearchOptions`).
    """

    iterations_per_frame: int = 5
    features: FeatureOptions = field(default_factory=FeatureOptions)
    links: tuple[str, ...] | None = None
    axis_points: int = 2
    width_weight: float = 1.0
    max_width_error: float = 0.15
    fit_widths: bool = True
    learn_edge_signs: bool = True
    start_size: bool = True
    conditioning: tuple[float, float, float] = (1.0, 10.0, 1000.0)
    use_conditioning: bool = True
    shading_correction: bool = True
    shading_every: int = 1
    blur_sigma_px: float = 0.0
    static_backdrop: bool = True
    max_backdrop_texture: float = 6.0
    damping: Damping = "fixed"
    robust_loss: RobustLoss | None = None
    robust_scale_px: float = 5.0
    clip_to_limits: bool = True
    prediction: PredictionKind = "none"
    form: StepForm = StepForm.TANGENT
    max_invalid_fraction: float = 0.5
    invalid_margin: float = 0.2
    max_residual_rms_px: float | None = None
    growth_frames: int = 5
    growth_factor: float = 2.0
    growth_min_px: float = 3.0

    def __post_init__(self) -> None:
        FingerSearchOptions.__post_init__(self)
        if isinstance(self.iterations_per_frame, bool) or not isinstance(
                self.iterations_per_frame, int | np.integer) or self.iterations_per_frame < 1:
            raise ValueError(
                f"iterations_per_frame must be a positive integer, got "
                f"{self.iterations_per_frame!r}"
            )
        if isinstance(self.axis_points, bool) or not isinstance(
                self.axis_points, int | np.integer) or self.axis_points < 1:
            raise ValueError(f"axis_points must be a positive integer, got {self.axis_points!r}")
        if not isinstance(self.features, FeatureOptions):
            raise ValueError(f"features must be a FeatureOptions, got {type(self.features)}")
        if self.links is not None:
            if isinstance(self.links, str) or not all(isinstance(n, str) for n in self.links):
                raise ValueError(f"links must be a sequence of link names, got {self.links!r}")
            object.__setattr__(self, "links", tuple(self.links))
        weights = tuple(float(w) for w in self.conditioning)
        if len(weights) != 3 or not all(np.isfinite(w) and w >= 0 for w in weights):
            raise ValueError(
                "conditioning must be three non-negative weights (quaternion, translation, "
                f"joint), got {self.conditioning!r}"
            )
        object.__setattr__(self, "conditioning", weights)
        if self.form not in STEP_FORMS:
            raise ValueError(f"form must be one of {', '.join(STEP_FORMS)}, got {self.form!r}")
        object.__setattr__(self, "form", StepForm.parse(self.form))
        choices = (("damping", DAMPINGS), ("prediction", PREDICTIONS))
        for name, allowed in choices:
            if getattr(self, name) not in allowed:
                raise ValueError(
                    f"{name} must be one of {', '.join(allowed)}, got {getattr(self, name)!r}"
                )
        if self.robust_loss is not None and self.robust_loss not in ROBUST_LOSSES:
            raise ValueError(
                f"robust_loss must be None, 'huber' or 'tukey', got {self.robust_loss!r}"
            )
        if not (np.isfinite(self.width_weight) and self.width_weight >= 0):
            raise ValueError(f"width_weight must be >= 0, got {self.width_weight!r}")
        positive = ["robust_scale_px", "growth_factor", "max_width_error",
                    "max_backdrop_texture", "max_unexplained", "max_finger_outside",
                    "invalid_margin"]
        if self.max_residual_rms_px is not None:
            positive.append("max_residual_rms_px")
        for name in positive:
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")
        if not 0.0 <= self.max_invalid_fraction <= 1.0:
            raise ValueError(
                f"max_invalid_fraction must be in [0, 1], got {self.max_invalid_fraction!r}"
            )
        if not isinstance(self.shading_every, int | np.integer) or self.shading_every < 1:
            raise ValueError(f"shading_every must be a positive integer, got "
                             f"{self.shading_every!r}")
        if not (np.isfinite(self.blur_sigma_px) and self.blur_sigma_px >= 0):
            raise ValueError(f"blur_sigma_px must be >= 0, got {self.blur_sigma_px!r}")
        if not isinstance(self.growth_frames, int | np.integer) or self.growth_frames < 1:
            raise ValueError(f"growth_frames must be a positive integer, got "
                             f"{self.growth_frames!r}")
        if not (np.isfinite(self.growth_min_px) and self.growth_min_px >= 0):
            raise ValueError(f"growth_min_px must be >= 0, got {self.growth_min_px!r}")
        if isinstance(self.silhouette_tolerance_px, bool) or not isinstance(
                self.silhouette_tolerance_px, int | np.integer) or \
                self.silhouette_tolerance_px < 0:
            raise ValueError(f"silhouette_tolerance_px must be an integer >= 0, got "
                             f"{self.silhouette_tolerance_px!r}")

    @property
    def residual_limit_px(self) -> float:
        """The residual RMS above which a frame is lost, pixels."""
        if self.max_residual_rms_px is not None:
            return float(self.max_residual_rms_px)
        return 0.5 * self.features.window_px


@dataclass
class FeatureDetails:
    """What the feature tracker measured in one frame, at its final state (the
    ``details`` of its :class:`~digiteyes.trackers.base.TrackResult`; the overlay draws
    them, :func:`digiteyes.viz.track_overlay.draw_result`).

    Attributes
    ----------
    measurements : one :class:`~digiteyes.features.measure.FeatureMeasurement` per camera.
    residual_layouts : one :class:`~digiteyes.features.residuals.ResidualLayout` per camera
        (which rows belong to which feature).
    residuals : (M,) final stacked residual vector over all cameras, px.
    n_valid_links, n_valid_tips : features measured at the final state, all cameras.
    n_features : features asked for (links + tips, times cameras).
    summary : the solver's :class:`~digiteyes.solvers.SolverSummary`.
    searched : the silhouette finger search moved a digit in this frame and the solve
        from there explained the silhouette better than the first estimate.
    """

    measurements: list[Any]
    residual_layouts: list[Any]
    residuals: np.ndarray
    n_valid_links: int
    n_valid_tips: int
    n_features: int
    summary: SolverSummary
    searched: bool = False


@dataclass
class _Evaluation:
    """One pass of measurement at a state: what the tracker reports for the final one."""

    q: np.ndarray
    measurements: list[Any]
    layouts: list[Any]
    residuals: np.ndarray


MoreRows = Callable[[Kinematics, bool], tuple[np.ndarray, "np.ndarray | None"]]
"""``rows(kin, jacobian)``: residuals (M,) at the kinematics ``kin`` of the iterate and, if
asked, their Jacobian (M, n_v) in the tracker's step form (:class:`FeatureProblem`)."""


class FeatureProblem:
    """Feature alignment at one set of frames as a least-squares problem: residuals are
    re-measured at every iterate (thesis Sec. 4.3.2 steps 1-5), in every camera, and
    stacked (thesis Sec. 2.5.5).

    Parameters
    ----------
    model, rig : the kinematic model and the cameras of ``images``.
    images : one prepared grey image per camera (:func:`~digiteyes.features.slices.
        prepare_image`), rig order.
    link_names, tip_names : the links and tips to measure.
    options : the tracker's settings (feature search, axis points, width residuals).
    parameterisation : the step form, retraction and projection.
    edge_bias : per camera, the predicted edge bias subtracted from the residuals (empty
        for none; :mod:`digiteyes.features.appearance`).
    timings : seconds per stage, added to in place.
    radius_scale : per link, the factor on its radius in the width residuals (None: 1;
        :mod:`digiteyes.features.width_scale`).
    more_rows : further residual rows from the same kinematics, stacked below the
        features' (e.g. a detector's keypoints, :mod:`digiteyes.trackers.anchored_features`);
        None: the features alone. The evaluations keep the features' rows only.
    side_signs : per camera, the (L, 2) edge sign of each measured link's sides
        (:mod:`digiteyes.features.edge_signs`); None: the usual signs everywhere.
    """

    def __init__(self, model: KinematicModel, rig: Rig, images: list[np.ndarray],
                 link_names: Sequence[str], tip_names: Sequence[str],
                 options: FeatureTrackerOptions, parameterisation: StateParameterisation,
                 edge_bias: Sequence[EdgeBias], timings: dict[str, float],
                 radius_scale: np.ndarray | None = None,
                 more_rows: MoreRows | None = None,
                 side_signs: Sequence[np.ndarray] | None = None) -> None:
        self.model = model
        self.rig = rig
        self.images = images
        self.link_names = list(link_names)
        self.tip_names = list(tip_names)
        self.options = options
        self.param = parameterisation
        self.edge_bias = list(edge_bias)
        self.timings = timings
        self.radius_scale = radius_scale
        self.more_rows = more_rows
        self.side_signs = side_signs
        self.n_v = self.param.n_v
        self.evaluations: list[_Evaluation] = []

    def residuals(self, q: np.ndarray, jacobian: bool) -> tuple[np.ndarray, np.ndarray | None]:
        opts, timings = self.options, self.timings
        start = time.perf_counter()
        kin = forward_kinematics(self.model, q)
        timings["forward_kinematics"] += time.perf_counter() - start
        rs, Js, measurements, layouts = [], [], [], []
        for index, (camera, image) in enumerate(zip(self.rig, self.images, strict=True)):
            start = time.perf_counter()
            meas = measure_features(image, camera, self.model, kin, opts.features,
                                    self.link_names, self.tip_names,
                                    None if self.side_signs is None else self.side_signs[index])
            timings["feature_detection"] += time.perf_counter() - start
            start = time.perf_counter()
            r, J, layout = feature_residuals(
                meas, camera, kin, jacobian=jacobian, form=self.param.form,
                axis_points=opts.axis_points, width_weight=opts.width_weight,
                max_width_error=opts.max_width_error, radius_scale=self.radius_scale)
            if self.edge_bias:
                r -= self.edge_bias[index].of_rows(layout.kind_code, layout.link_index,
                                                   layout.component)
            rs.append(r)
            Js.append(J)
            measurements.append(meas)
            layouts.append(layout)
            timings["jacobian"] += time.perf_counter() - start
        start = time.perf_counter()
        r = np.concatenate(rs)
        J = np.concatenate(Js) if jacobian else None
        timings["jacobian"] += time.perf_counter() - start
        self.evaluations.append(_Evaluation(np.array(q), measurements, layouts, r))
        if self.more_rows is not None:
            r_more, J_more = self.more_rows(kin, jacobian)
            r = np.concatenate([r, r_more])
            J = np.concatenate([J, J_more]) if jacobian else None
        return r, J

    def retract(self, q: np.ndarray, dv: np.ndarray) -> np.ndarray:
        return self.param.retract(q, dv)

    def project(self, q: np.ndarray) -> np.ndarray:
        return self.param.project(q)

    def evaluation_at(self, q: np.ndarray) -> _Evaluation:
        """The latest evaluation at exactly ``q`` (measuring again if there was none)."""
        for evaluation in reversed(self.evaluations):
            if np.array_equal(evaluation.q, q):
                return evaluation
        self.residuals(q, False)
        return self.evaluations[-1]


class FeatureTracker:
    """Track a kinematic model through point and line features (DigitEyes).

    Parameters
    ----------
    model : the kinematic model (any model file works, thesis Sec. 4.2).
    rig : the calibrated cameras; :meth:`step` takes one image per camera, in rig order.
    options : :class:`FeatureTrackerOptions`.

    Examples
    --------
    >>> tracker = FeatureTracker(load_model("hand"), rig)          # doctest: +SKIP
    >>> tracker.reset(initial_state)                                # doctest: +SKIP
    >>> for frames in video:                                        # doctest: +SKIP
    ...     result = tracker.step(frames)
    ...     print(result.state, result.residual_rms_px, result.lost)
    """

    stages = ("prediction", "shading", "forward_kinematics", "feature_detection",
              "jacobian", "linear_solve", "silhouette", "finger_search")
    """Timing stages of :attr:`TrackResult.timings` (thesis Table 4.1 rows, plus the
    prediction and the shading prediction): ``"jacobian"`` is residual and Jacobian
    assembly, ``"linear_solve"`` the normal equations, solve and state update,
    ``"silhouette"`` the silhouette check of the loss rules, ``"finger_search"`` the
    silhouette finger search and the solve from its result (frames the rule calls lost;
    their feature and solver time is counted here, not in the stages above)."""

    def __init__(self, model: KinematicModel, rig: Rig,
                 options: FeatureTrackerOptions | None = None) -> None:
        self.rig = rig
        self.options = FeatureTrackerOptions() if options is None else options
        opts = self.options
        self.sizing = StartSize(model, opts.start_size)
        self.link_names, self.tip_names = feature_names(model, opts.links)
        self.n_features = (len(self.link_names) + len(self.tip_names)) * len(rig)
        self._build(model)
        self._rms_history: deque[float] = deque(maxlen=opts.growth_frames)
        self._frame_index = 0
        self.state: np.ndarray | None = None
        self.shading: ShadingModel | None = None
        self.edge_bias: list[EdgeBias] = []
        self.loss_hold = LossHold(opts.hold_lost_frames)
        self._invalid_baseline: float | None = None
        self.radius_scale: np.ndarray | None = None
        """Per link, the factor on its radius (``fit_widths``; None until a frame's state
        fits the image)."""
        self._widths_tried = False
        self.side_signs: list[np.ndarray] | None = None

    @property
    def scale(self) -> float | None:
        """The size of the tracked hand relative to the model file (``start_size``; None
        when the tracker does not size the hand)."""
        return self.sizing.scale

    def _build(self, model: KinematicModel) -> None:
        """Everything that depends on the tracked model (``model``: the model file's or
        the measured size's): the step form, the solver's conditioning, the prediction,
        the silhouette rule and the finger search."""
        opts = self.options
        self.model = model
        self.parameterisation = StateParameterisation(model, opts.form, opts.clip_to_limits)
        conditioning = None
        if opts.use_conditioning:
            conditioning = hand_conditioning(model, *opts.conditioning, form=opts.form)
        self.solver_options = GaussNewtonOptions(
            max_iterations=opts.iterations_per_frame, conditioning=conditioning,
            damping=opts.damping, robust_loss=opts.robust_loss,
            scale_px=opts.robust_scale_px, step_tolerance=0.0, cost_tolerance=0.0)
        self.predictor = StatePredictor(model, opts.prediction, opts.clip_to_limits)
        self.silhouette_loss = SilhouetteLoss.from_options(model, self.rig, opts)
        self.finger_recovery = FingerRecovery(model, self.silhouette_loss, opts)

    def reset(self, initial_state: np.ndarray, shading: ShadingModel | None = None) -> None:
        """Start a new track from ``initial_state`` (n_q,); a non-unit quaternion is
        normalised, joint states are clipped into their limits when ``clip_to_limits``.

        With ``shading_correction``, ``shading`` is the scene's shading model; None fits
        one (:func:`~digiteyes.features.appearance.fit_shading`) on the first frame at
        ``initial_state``, which must therefore show the model where it is."""
        q = np.asarray(getattr(initial_state, "q", initial_state), dtype=float)
        if (model := self.sizing.forget()) is not None:  # a new track: size unknown again
            self._build(model)
        self._start(q)
        # a new scene: what the first frame fits is fitted again
        self.shading = shading
        self.silhouette_loss.reset()
        self.radius_scale = None
        self._widths_tried = False
        self.side_signs = None

    def _start(self, initial_state: np.ndarray) -> None:
        """What every track starts afresh, a new one (:meth:`reset`) or the same scene's
        after a re-detection (:meth:`restart`): the state, the motion history, the edge
        bias, the silhouette rule's baselines, the finger recovery and the loss hold."""
        q = initial_state
        if q.shape != (self.model.n_q,):
            raise StateError(
                f"initial state must hold {self.model.n_q} numbers for model "
                f"{self.model.name!r}, got shape {q.shape}"
            )
        q = self.parameterisation.project(validate_state(self.model, q, normalize=True))
        self.state = q
        self.predictor.reset(q)
        self._rms_history.clear()
        self._frame_index = 0
        self.edge_bias = []
        self.silhouette_loss.rebaseline()
        self.finger_recovery.reset()
        self.loss_hold.reset()
        self._invalid_baseline = None

    def restart(self, state: np.ndarray) -> None:
        """Continue the same scene from ``state`` (n_q,) after a re-detection: the motion
        history is dropped and the silhouette baselines are taken anew at ``state``, but
        the shading model, its backdrop, the foreground colours, the link widths, the
        edge signs and the hand's size of the first frame stay, so a recovery costs no
        refit."""
        self._start(np.asarray(state, dtype=float))
        self._widths_tried = True
        self.sizing.pending = False

    def step(self, frames: Sequence[np.ndarray]) -> TrackResult:
        """Estimate the state for one set of frames (one image per camera, rig order).

        Raises :class:`~digiteyes.errors.CameraError` when the frames do not fit the rig
        and :class:`~digiteyes.errors.StateError` before :meth:`reset`.
        """
        start_total, timings = start_step(self, frames)
        start = time.perf_counter()
        predicted = self.predictor.predict()
        timings["prediction"] = time.perf_counter() - start
        start = time.perf_counter()
        # one image type for the frames and the shading prediction (float32): the
        # feature kernels are then compiled once, not twice (uint8 and float32)
        images = [prepare_image(frame).astype(np.float32, copy=False) for frame in frames]
        timings["feature_detection"] += time.perf_counter() - start
        if self.sizing.pending:  # before the shading fit, which draws the model
            start = time.perf_counter()
            self._measure_size(images, predicted)
            timings["feature_detection"] += time.perf_counter() - start
        if self.side_signs is None and self.options.learn_edge_signs:
            start = time.perf_counter()
            kin = forward_kinematics(self.model, predicted)
            self.side_signs = [learn_side_signs(image, camera, self.model, kin,
                                                self.options.features, self.link_names,
                                                self.tip_names)
                               for camera, image in zip(self.rig, images, strict=True)]
            timings["feature_detection"] += time.perf_counter() - start
        if self.options.shading_correction:
            start = time.perf_counter()
            self._predict_edge_bias(images, predicted)
            timings["shading"] = time.perf_counter() - start
        if not self._widths_tried and self._widths_wanted():
            start = time.perf_counter()
            self.radius_scale = self._fit_widths(images, predicted)
            self._widths_tried = True
            timings["feature_detection"] += time.perf_counter() - start
        problem = FeatureProblem(self.model, self.rig, images, self.link_names,
                                 self.tip_names, self.options, self.parameterisation,
                                 self.edge_bias, timings, self.radius_scale,
                                 self._more_rows(frames, timings), self.side_signs)
        q, summary = gauss_newton(problem, predicted, self.solver_options)
        timings["linear_solve"] = summary.timings["linear_solve"]
        final = problem.evaluation_at(q)
        start = time.perf_counter()
        verdict = (self.silhouette_loss.check(images, q, predicted, colours=frames)
                   if self.options.silhouette_check else None)
        timings["silhouette"] = time.perf_counter() - start
        searched = False
        digits = [] if verdict is None else self.finger_recovery.digits_to_search(verdict)
        if digits:
            start = time.perf_counter()
            found = self._search_fingers(problem, images, frames, q, predicted, digits)
            if found is not None:
                q, summary, final, verdict, moved = found
                self.finger_recovery.placed(moved)
                searched = True
            timings["finger_search"] = time.perf_counter() - start
        if verdict is not None:
            verdict = self.finger_recovery.judge(verdict)
        result = self._result(q, predicted, summary, final, timings, verdict)
        result.details.searched = searched
        if self._widths_wanted() and not result.lost:
            # the start did not fit the image (an automatic start, centimetres off): the
            # widths are measured on the first frame whose solved state does
            start = time.perf_counter()
            self.radius_scale = self._fit_widths(images, q)
            timings["feature_detection"] += time.perf_counter() - start
        self.state = q
        self.predictor.update(q, reliable=not (result.lost or searched))
        self._frame_index += 1
        timings["total"] = time.perf_counter() - start_total
        return self.finger_recovery.hold(self.loss_hold, result, searched)

    def _more_rows(self, frames: Sequence[np.ndarray], timings: dict[str, float]
                   ) -> MoreRows | None:
        """Residual rows to stack below the features' in this frame's solves (the frames
        as given, rig order; ``timings`` to account their cost in): None here, the
        features alone; a subclass adds its own (:mod:`digiteyes.trackers.anchored_features`)."""
        return None

    def _search_fingers(self, problem: FeatureProblem, images: list[np.ndarray],
                        frames: Sequence[np.ndarray], q: np.ndarray, predicted: np.ndarray,
                        digits: list[str]) -> tuple | None:
        """The silhouette finger search of ``digits`` from ``q`` and a solve
        from its result (``images`` grey, ``frames`` as they came); (state, summary,
        evaluation, verdict, digits moved) of that solve if it explains the silhouette
        better than ``q``, else None. The solve's timings go to the search's stage."""
        searched = self.finger_recovery.search(images, q, digits, colours=frames)
        if searched is None:
            return None
        start, moved = searched
        problem.timings = dict.fromkeys(problem.timings, 0.0)
        found, summary = gauss_newton(problem, start, self.solver_options)
        if not self.finger_recovery.improves(images, q, found, colours=frames):
            return None
        return (found, summary, problem.evaluation_at(found),
                self.silhouette_loss.check(images, found, predicted, colours=frames), moved)

    def _size_settings(self) -> dict:
        """The tracker's feature settings for the size measurement
        (:func:`~digiteyes.trackers.feature_size.hand_size_at`; no width rows: they measure
        how thick the fingers look, not how long)."""
        opts = self.options
        return {"features": opts.features, "link_names": self.link_names,
                "tip_names": self.tip_names, "axis_points": opts.axis_points,
                "loss": opts.robust_loss, "scale_px": opts.robust_scale_px}

    def start_size_at(self, images: list[np.ndarray], q: np.ndarray) -> float:
        """The size of the hand in ``images`` (one image per camera) relative to the model
        file, measured at its known state ``q`` (n_q,; translation in mm) from the
        tracker's features (:func:`~digiteyes.trackers.feature_size.hand_size_at`)."""
        return hand_size_at(self.sizing.nominal_model, self.rig, images, q,
                            **self._size_settings())

    def _measure_size(self, images: list[np.ndarray], q: np.ndarray) -> None:
        """On the first frame: the hand's size at the start state ``q``; a size other than
        the model file's rebuilds the tracker on a model of that size."""
        if (model := self.sizing.measure(self.rig, images, q,
                                         **self._size_settings())) is not None:
            self._build(model)
            self.predictor.reset(q)

    def _widths_wanted(self) -> bool:
        """Whether the links' widths are still to be measured (``fit_widths``, one
        camera, width residuals on, none measured yet)."""
        return (self.radius_scale is None and self.options.fit_widths and len(self.rig) == 1
                and self.options.width_weight > 0)

    def _fit_widths(self, images: list[np.ndarray], q: np.ndarray) -> np.ndarray | None:
        """Each link's radius factor from the features measured at ``q`` (the start of
        the track, or a later frame's solved state), or None when too few links lie where
        ``q`` puts them (:func:`~digiteyes.features.width_scale.link_radius_scales`)."""
        opts = self.options
        kin = forward_kinematics(self.model, q)
        signs = self.side_signs or [None] * len(self.rig)
        measurements = [measure_features(image, camera, self.model, kin, opts.features,
                                         self.link_names, self.tip_names, sign)
                        for camera, image, sign in zip(self.rig, images, signs, strict=True)]
        return link_radius_scales(measurements, list(self.rig), kin, self.edge_bias,
                                  opts.axis_points, opts.width_weight)

    def _predict_edge_bias(self, images: list[np.ndarray], predicted: np.ndarray) -> None:
        """Fit the shading model on the first frame, then predict each camera's edge bias
        at the predicted state every ``shading_every`` frames (never over a textured
        backdrop)."""
        opts = self.options
        if self.shading is None:
            self.shading = fit_shading(images, self.rig, self.model, predicted,
                                       opts.blur_sigma_px, opts.static_backdrop)
        if self.shading.backdrop_texture > opts.max_backdrop_texture:
            return
        if self._frame_index % opts.shading_every == 0 or not self.edge_bias:
            self.edge_bias = [
                edge_bias(self.shading, self.model, predicted, camera, opts.features,
                          self.link_names, self.tip_names, axis_points=opts.axis_points,
                          width_weight=opts.width_weight,
                          max_width_error=opts.max_width_error)
                for camera in self.rig]

    def _result(self, q: np.ndarray, predicted: np.ndarray, summary: SolverSummary,
                final: _Evaluation, timings: dict[str, float],
                verdict: SilhouetteVerdict | None) -> TrackResult:
        r = final.residuals
        rms = float(np.sqrt(np.mean(r * r))) if len(r) else float("nan")
        n_links = int(sum(int(np.sum(m.link_valid)) for m in final.measurements))
        n_tips = int(sum(int(np.sum(m.tip_valid)) for m in final.measurements))
        if self._invalid_baseline is None:
            self._invalid_baseline = 1.0 - (n_links + n_tips) / self.n_features
        reasons = track_loss_reasons(rms, n_links + n_tips, self.n_features,
                                     list(self._rms_history), self.options,
                                     self._invalid_baseline)
        finger_lost = verdict.finger_lost if verdict else {}
        if verdict and reasons != [NO_FEATURES]:
            reasons += verdict.reasons
        if np.isfinite(rms):
            self._rms_history.append(rms)
        else:
            self._rms_history.clear()
        details = FeatureDetails(
            measurements=final.measurements, residual_layouts=final.layouts, residuals=r,
            n_valid_links=n_links, n_valid_tips=n_tips, n_features=self.n_features,
            summary=summary)
        return TrackResult(
            state=q, cost=summary.cost_final, residual_rms_px=rms, lost=bool(reasons),
            loss_reason="; ".join(reasons), iterations=summary.iterations,
            predicted_state=predicted, frame_index=self._frame_index, timings=timings,
            finger_lost=finger_lost, details=details,
            hand_scale=self.sizing.hand_scale)


def track_loss_reasons(rms: float, n_valid: int, n_features: int, previous_rms: Sequence[float],
                       options: FeatureTrackerOptions, first_invalid: float = 0.0
                       ) -> list[str]:
    """The track-loss rules (module docstring) for one frame; empty when the track holds.

    Parameters
    ----------
    rms : final residual RMS of the frame, px (NaN without residuals).
    n_valid : valid features (links + tips, all cameras) at the final state.
    n_features : features asked for (links + tips, times cameras).
    previous_rms : residual RMS of the preceding frames, oldest first (the growth rule
        looks at the last ``options.growth_frames`` of them).
    options : the thresholds.
    first_invalid : fraction of the features invalid in the first frame of the track.
    """
    if n_valid == 0 or not np.isfinite(rms):
        return [NO_FEATURES]
    reasons = []
    invalid = 1.0 - n_valid / n_features
    if invalid > max(options.max_invalid_fraction, first_invalid + options.invalid_margin):
        reasons.append(f"{invalid:.0%} of the features invalid "
                       f"(limit {options.max_invalid_fraction:.0%})")
    if rms > options.residual_limit_px:
        reasons.append(f"residual RMS {rms:.2f} px > {options.residual_limit_px:.2f} px")
    k = options.growth_frames
    if len(previous_rms) >= k:
        values = np.append(np.asarray(previous_rms, dtype=float)[-k:], rms)
        if (np.all(np.diff(values) > 0) and rms > options.growth_factor * values[0]
                and rms > options.growth_min_px):
            reasons.append(f"residual RMS grew from {values[0]:.2f} to {rms:.2f} px over "
                           f"{k} frames")
    return reasons
