"""Layered template trackers (Rehg thesis Ch. 3 and Sec. 4.4; real time and several
cameras, the future work of Ch. 6).

Per frame:

1. predict the state (previous estimate, or constant velocity);
2. per camera: LoG-filter the image, turn the template planes to face the camera and
   predict the visibility order at the predicted state (Sec. 3.2, 3.4; order and planes
   are held over the frame's iterations, as in the thesis);
3. a few iterations of stabilised Gauss-Newton (eq. 2.22) or fixed-step gradient descent
   (eq. 2.12) on the layered template error of all cameras
   (:mod:`digiteyes.templates.layered`), normal equations accumulated directly;
   :class:`LayeredFeatureTracker` stacks the edge features of the feature tracker
   (thesis Sec. 2.5) for the links no other part occludes into the same system;
4. track-loss rules, then the template refresh (only on frames that are not lost).

Track loss: a frame is ``lost`` when the visibility-weighted template residual RMS
exceeds ``max_residual_rms`` (grey levels of the filtered image), when fewer than
``min_visible_fraction`` of the acquired template pixels are visible in all cameras, or
when the RMS grew over ``growth_frames`` frames to ``growth_factor`` times its value
(and above ``growth_min``); these residual rules gate the template refresh and the
prediction (frames they call lost refresh nothing). With ``silhouette_check`` (a plain
backdrop), the silhouette rule of the feature tracker
(:mod:`digiteyes.trackers.silhouette_loss`, the same thresholds) also flags the frame and
its fingers: the template residual stays small when a finger's template has slid onto
skin of the palm or a neighbour (docs/accuracy.md). It reports only, so the track itself
is the same with it on or off.

The templates are acquired from the first frame at the state given to :meth:`reset`.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from digiteyes.camera import Rig
from digiteyes.errors import StateError
from digiteyes.features import FeatureOptions, feature_residuals, measure_features
from digiteyes.features.slices import prepare_image
from digiteyes.kinematics import KinematicModel, Kinematics, forward_kinematics, validate_state
from digiteyes.kinematics.anatomy import DIGITS
from digiteyes.occlusion.parts import TemplatePlane, template_parts
from digiteyes.occlusion.segmentation import segment_image
from digiteyes.occlusion.visibility import (
    VisibilityOrder,
    occlusion_events,
    predict_visibility,
)
from digiteyes.occlusion.windows import ImageWindows, image_windows
from digiteyes.solvers import SolverSummary, hand_conditioning, solve_normal_equations
from digiteyes.templates.background import (
    BackgroundTemplate,
    acquire_background,
    evaluate_background,
    window_region,
)
from digiteyes.templates.deformation import part_twists
from digiteyes.templates.filtering import TemplateError
from digiteyes.templates.layered import (
    CameraTemplates,
    LayeredEvaluation,
    TemplateOptions,
    acquire_templates,
    evaluate_layered,
    refresh_templates,
)
from digiteyes.trackers.base import TrackResult, start_step
from digiteyes.trackers.feature_size import StartSize
from digiteyes.trackers.finger_search import FingerRecovery, FingerSearchOptions
from digiteyes.trackers.loss_hold import LossHold, LossHoldOptions
from digiteyes.trackers.parameterisation import StateParameterisation
from digiteyes.trackers.prediction import PREDICTIONS, PredictionKind, StatePredictor
from digiteyes.trackers.silhouette_loss import (
    SilhouetteLoss,
    SilhouetteLossOptions,
    SilhouetteVerdict,
)

TEMPLATE_TIMING_STAGES = ("prediction", "filtering", "visibility", "template_rendering",
                          "residual", "jacobian", "features", "linear_solve", "refresh",
                          "silhouette", "finger_search")
"""Stages of :attr:`TrackResult.timings` for the template trackers (seconds; ``"total"``
is reported too). ``template_rendering`` is placing the template pixels (planes, points,
projection), ``residual`` the compiled pass that samples the image and sums the error and
normal equations, ``jacobian`` chaining the twist and window sums into ``H`` and ``g``,
``features`` the edge features of the combined tracker (measurement, residuals, Jacobian;
0 for the templates alone), ``silhouette`` the silhouette loss rule, ``finger_search``
the silhouette finger search and its re-solve (only on frames the rule calls lost)."""

SOLVERS = ("gauss-newton", "gradient-descent")
BACKGROUNDS = ("none", "filtered", "grey")


@dataclass(frozen=True)
class LayeredTemplateOptions(SilhouetteLossOptions, LossHoldOptions, FingerSearchOptions):
    """Settings of :class:`LayeredTemplateTracker`.

    Attributes
    ----------
    templates : template, filter, window and refresh settings.
    iterations_per_frame : solver iterations per frame (thesis Sec. 4.4: 2).
    solver : ``"gauss-newton"`` (eq. 2.22) or ``"gradient-descent"`` (eq. 2.12).
    step_size : gradient-descent step (state units per unit of scaled gradient).
    template_weight : the template error is multiplied by this (1 / grey level^2), so a
        residual of ``1 / sqrt(template_weight)`` grey levels weighs like a pixel of
        feature residual against the conditioning ``S``.
    conditioning : ``S`` weights (rotation, translation, joint angle) of eq. 2.22. A
        thousand times the feature tracker's (1, 10, 1000): ``S`` must stand in
        proportion to the curvature ``H`` of the error it stabilises, and the template
        error sums thousands of pixels a link (correlated: the LoG filter and the
        template's own mismatch), so its ``H`` is 100-1000 times the features' for the
        same motion. With the features' ``S`` the template solve was undamped along the
        near-null directions (a finger's three flexions towards the camera trade
        against each other): on ``two-finger-occlusion`` the unmoved middle finger's DIP
        drifted that way, carried on by the velocity prediction, to its limit (1.57 rad)
        on every seed and appearance; with ``S`` x 1000 it stays within 0.04-0.06 rad
        (docs/templates.md, "Conditioning").
    prediction : ``"none"`` or ``"constant-velocity"``.
    clip_to_limits : clip joint states into their limits after every step.
    edge_features : stack edge features of unoccluded links (the combined tracker).
    features : feature-search settings of the combined tracker.
    feature_weight : weight of the feature residuals (px) against the template error.
    max_residual_rms : loss rule, grey levels.
    min_visible_fraction : loss rule: visible share of the acquired template pixels.
    growth_frames, growth_factor, growth_min : loss rule on a residual that grew in each
        of the last ``growth_frames`` frames to ``growth_factor`` times its value and
        above ``growth_min`` grey levels.
    silhouette_check, silhouette_tolerance_px, max_unexplained, max_finger_outside : the
        silhouette loss rule (:class:`~digiteyes.trackers.silhouette_loss.SilhouetteLoss`;
        defaults as the feature tracker's).
    background : the background template of thesis Sec. 4.4.2
        (:mod:`digiteyes.templates.background`; a static camera, smooth windows):
        ``"none"``, ``"filtered"`` (compared in the LoG-filtered image, as the templates)
        or ``"grey"`` (in the plain grey image, where a finger and the backdrop differ
        inside the outline too, not only at edges).
    background_weight : its error's weight, times ``template_weight``.
    background_pad_px : how far around the hand's windows its pixels reach, px.
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
    start_size : on the first frame of a track, before the templates are acquired,
        measure the hand's size at the start state from the feature tracker's line and
        tip features (:mod:`digiteyes.trackers.feature_size`) and track a model of that
        size; the start must be the hand's pose (``digiteyes track`` turns it off for a
        start fitted from the images or placed by eye on footage). Results carry the
        size as :attr:`~digiteyes.trackers.TrackResult.hand_scale`.
    """

    templates: TemplateOptions = field(default_factory=TemplateOptions)
    iterations_per_frame: int = 3
    solver: str = "gauss-newton"
    step_size: float = 1e-4
    template_weight: float = 0.1
    conditioning: tuple[float, float, float] = (1e3, 1e4, 1e6)
    prediction: PredictionKind = "constant-velocity"
    clip_to_limits: bool = True
    edge_features: bool = False
    features: FeatureOptions = field(default_factory=FeatureOptions)
    feature_weight: float = 1.0
    max_residual_rms: float = 40.0
    min_visible_fraction: float = 0.2
    growth_frames: int = 5
    growth_factor: float = 2.5
    growth_min: float = 15.0
    background: str = "none"
    background_weight: float = 1.0
    background_pad_px: float = 20.0
    start_size: bool = True

    def __post_init__(self) -> None:
        FingerSearchOptions.__post_init__(self)
        if isinstance(self.iterations_per_frame, bool) or int(self.iterations_per_frame) != \
                self.iterations_per_frame or self.iterations_per_frame < 1:
            raise TemplateError(f"iterations_per_frame must be a positive integer, got "
                                f"{self.iterations_per_frame!r}")
        if self.solver not in SOLVERS:
            raise TemplateError(f"solver must be one of {', '.join(SOLVERS)}, got "
                                f"{self.solver!r}")
        if self.prediction not in PREDICTIONS:
            raise TemplateError(f"prediction must be one of {', '.join(PREDICTIONS)}, got "
                                f"{self.prediction!r}")
        for name in ("step_size", "template_weight", "max_residual_rms", "growth_factor"):
            if not getattr(self, name) > 0:
                raise TemplateError(f"{name} must be positive, got {getattr(self, name)!r}")
        if not 0.0 <= self.min_visible_fraction <= 1.0:
            raise TemplateError(f"min_visible_fraction must be in [0, 1], got "
                                f"{self.min_visible_fraction!r}")
        if self.background not in BACKGROUNDS:
            raise TemplateError(f"background must be one of {', '.join(BACKGROUNDS)}, got "
                                f"{self.background!r}")
        if not self.background_weight > 0 or not self.background_pad_px >= 0:
            raise TemplateError("background_weight must be positive and background_pad_px "
                                "not negative")


@dataclass
class TemplateDetails:
    """What the template trackers report beyond the common :class:`TrackResult` core.

    Attributes
    ----------
    templates : the templates of each camera after this frame's refresh.
    orders : the visibility order of each camera (predicted at the predicted state).
    events : occlusion events of each camera since the last frame
        (:func:`~digiteyes.occlusion.visibility.occlusion_events`).
    evaluations : the layered error of each camera at the final state (residuals ``r``,
        visibility ``V``, image positions, windows).
    planes : the template planes of each camera used in this frame.
    image_sizes : (width, height) px of each camera's image.
    visible_fraction : share of the acquired template pixels that were visible.
    residual_rms : visibility-weighted template residual RMS, grey levels.
    feature_links : links whose edge features were used (combined tracker), per camera.
    refreshed : template pixels refreshed in this frame, all cameras.
    summary : the solver's :class:`~digiteyes.solvers.SolverSummary` (costs per
        iteration, step norms, termination).
    finger_rms : finger name -> visibility-weighted template residual RMS of its parts,
        grey levels (NaN when none of its pixels is visible).
    residual_lost : the template residual rules called the frame lost (they gate the
        refresh and the prediction; the silhouette rule only reports).
    searched : the silhouette finger search moved a digit in this frame and the solve
        from there explained the silhouette better than the first estimate.
    """

    templates: list[CameraTemplates]
    orders: list[VisibilityOrder]
    events: list[list[tuple[str, int, int]]]
    evaluations: list[LayeredEvaluation]
    planes: list[list[TemplatePlane]]
    image_sizes: list[tuple[int, int]]
    visible_fraction: float
    residual_rms: float
    feature_links: list[list[str]]
    refreshed: int
    summary: SolverSummary
    finger_rms: dict[str, float]
    residual_lost: bool = False
    searched: bool = False

    @cached_property
    def segmentations(self) -> list[np.ndarray]:
        """(H, W) int16 part index per pixel of each camera (list priority), drawn when
        first asked for (the overlay does; tracking does not need it)."""
        return [segment_image(ev.windows, order, width, height)
                for ev, order, (width, height) in zip(self.evaluations, self.orders,
                                                      self.image_sizes, strict=True)]


class LayeredTemplateTracker:
    """Track a kinematic model with layered templates (thesis Ch. 3).

    Parameters
    ----------
    model : the kinematic model.
    rig : the cameras; :meth:`step` takes one image per camera in rig order.
    options : :class:`LayeredTemplateOptions`.

    Each :class:`TrackResult` carries a :class:`TemplateDetails` as ``result.details``;
    ``result.finger_lost`` flags each finger whose visible template pixels have a residual
    RMS above ``max_residual_rms`` (a hidden finger is not lost), or that the silhouette
    rule finds over the backdrop.
    Registered as tracker ``"templates"``.
    """

    stages = TEMPLATE_TIMING_STAGES
    residual_unit = "grey level"
    """:attr:`TrackResult.residual_rms_px` holds the visible template residual's RMS in
    grey levels of the LoG-filtered image (0-255 scale), not pixels."""

    def __init__(self, model: KinematicModel, rig: Rig,
                 options: LayeredTemplateOptions | None = None) -> None:
        self.rig = rig
        self.options = LayeredTemplateOptions() if options is None else options
        self.sizing = StartSize(model, self.options.start_size)
        self._build(model)
        self.templates: list[CameraTemplates] = []
        self.backgrounds: list[BackgroundTemplate] = []
        self.state: np.ndarray | None = None
        self._orders: list[VisibilityOrder | None] = []
        self._rms_history: deque[float] = deque(maxlen=self.options.growth_frames)
        self._frame_index = 0
        self.loss_hold = LossHold(self.options.hold_lost_frames)

    @property
    def scale(self) -> float | None:
        """The size of the tracked hand relative to the model file (``start_size``; None
        when the tracker does not size the hand)."""
        return self.sizing.scale

    def _build(self, model: KinematicModel) -> None:
        """Everything that depends on the tracked model (``model``: the model file's or
        the measured size's): the template parts, the step form, the conditioning, the
        prediction, the feature links, the silhouette rule and the finger search."""
        opts = self.options
        self.model = model
        self.parts = template_parts(model)
        self.parameterisation = StateParameterisation(model, "tangent", opts.clip_to_limits)
        self.S = hand_conditioning(model, *opts.conditioning)
        self._rig_templates = opts.templates.for_rig(len(self.rig))  # as this rig uses them
        self.predictor = StatePredictor(model, opts.prediction, opts.clip_to_limits)
        self._feature_links = [link.name for link in model.links if link.kind == "link"]
        self._part_of_link = {p.link: k for k, p in enumerate(self.parts)}
        self._fingers: dict[str, list[int]] = {}
        for k, part in enumerate(self.parts):
            finger = part.name.split(".")[0]
            if part.kind != "palm" and finger in DIGITS:
                self._fingers.setdefault(finger, []).append(k)
        self.silhouette_loss = SilhouetteLoss.from_options(model, self.rig, opts)
        self.finger_recovery = FingerRecovery(model, self.silhouette_loss, opts)

    def reset(self, initial_state: np.ndarray) -> None:
        """Start a new track from ``initial_state`` (n_q,); the templates are acquired
        from the next frame at this state."""
        q = np.asarray(getattr(initial_state, "q", initial_state), dtype=float)
        if (model := self.sizing.forget()) is not None:  # a new track: size unknown again
            self._build(model)
        if q.shape != (self.model.n_q,):
            raise StateError(f"initial state must hold {self.model.n_q} numbers for model "
                             f"{self.model.name!r}, got shape {q.shape}")
        q = self.parameterisation.project(validate_state(self.model, q, normalize=True))
        self.state = q
        self.predictor.reset(q)
        self.templates = []
        self.backgrounds = []
        self._orders = [None] * len(self.rig)
        self._rms_history.clear()
        self._frame_index = 0
        self.silhouette_loss.reset()
        self.finger_recovery.reset()
        self.loss_hold.reset()

    # ------------------------------------------------------------------ per frame
    def step(self, frames: Sequence[np.ndarray]) -> TrackResult:
        """Estimate the state for one set of frames (one image per camera)."""
        start_total, timings = start_step(self, frames)
        tic = time.perf_counter()
        predicted = self.predictor.predict()
        timings["prediction"] = time.perf_counter() - tic
        tic = time.perf_counter()
        topts = self.options.templates
        greys = [prepare_image(f) for f in frames]  # once: filter, features, silhouette
        images = None
        if not self.templates:
            images = [topts.log.apply(g) for g in greys]
        timings["filtering"] = time.perf_counter() - tic
        if self.sizing.pending:  # before the templates are acquired
            tic = time.perf_counter()
            if (model := self.sizing.measure(self.rig, greys, predicted,
                                             features=self.options.features)) is not None:
                self._build(model)
                self.predictor.reset(predicted)
            timings["features"] += time.perf_counter() - tic
        if not self.templates:
            kin = forward_kinematics(self.model, predicted)
            self.templates = [acquire_templates(self.parts, image, cam, kin, topts.spacing_px,
                                                topts.occlusion_margin_px,
                                                self._rig_templates.pixel_depth_at_joints)
                              for image, cam in zip(images, self.rig, strict=True)]
            if self.options.background != "none":
                self.backgrounds = [
                    acquire_background(image, image_windows(self.parts, t.planes(kin, cam),
                                                            kin, cam),
                                       topts.occlusion_margin_px, self.options.background_pad_px)
                    for image, cam, t in zip(self._background_images(images, greys),
                                             self.rig, self.templates, strict=True)]
        setup = self._frame_setup(predicted, timings)
        if images is None:
            tic = time.perf_counter()
            images = [topts.log.apply(g, self._filter_region(windows))
                      for g, windows in zip(greys, setup["windows"], strict=True)]
            timings["filtering"] += time.perf_counter() - tic
        q, summary = self._solve(predicted, images, greys, setup, timings)
        kin = forward_kinematics(self.model, q)  # the final evaluation's and the refresh's
        final = self._evaluate_all(q, images, setup, timings, kin, derivatives=False)
        verdict = None
        searched = False
        if self.options.silhouette_check:
            tic = time.perf_counter()
            verdict = self.silhouette_loss.check(greys, q, predicted, colours=frames)
            timings["silhouette"] = time.perf_counter() - tic
            digits = self.finger_recovery.digits_to_search(verdict)
            if digits:
                tic = time.perf_counter()
                found = self._search_fingers(q, greys, frames, predicted, timings, digits)
                if found is not None:
                    q, summary, final, setup, verdict, moved = found
                    kin = forward_kinematics(self.model, q)
                    self.finger_recovery.placed(moved)
                    searched = True
                timings["finger_search"] = time.perf_counter() - tic
            verdict = self.finger_recovery.judge(verdict)
        result = self._result(q, kin, predicted, summary, final, setup, timings, verdict)
        result.details.searched = searched
        self.state = q
        self.predictor.update(q, reliable=not (result.details.residual_lost or searched))
        self._frame_index += 1
        timings["total"] = time.perf_counter() - start_total
        return self.finger_recovery.hold(self.loss_hold, result, searched)

    def _search_fingers(self, q: np.ndarray, greys: list[np.ndarray],
                        frames: Sequence[np.ndarray], predicted: np.ndarray,
                        timings: dict[str, float], digits: list[str]) -> tuple | None:
        """The silhouette finger search of ``digits`` from ``q`` and a solve
        from its result (``frames`` as they came, for the silhouette's colour model);
        (state, summary, evaluations, setup, verdict, digits moved) of that solve if it
        explains the silhouette better than ``q``, else None. The solve filters whole
        images: a moved finger may lie beyond the region filtered for the prediction."""
        searched = self.finger_recovery.search(greys, q, digits, colours=frames)
        if searched is None:
            return None
        start, moved = searched
        images = [self.options.templates.log.apply(g) for g in greys]
        setup = self._frame_setup(start, timings)
        found, summary = self._solve(start, images, greys, setup, timings)
        if not self.finger_recovery.improves(greys, q, found, colours=frames):
            return None
        final = self._evaluate_all(found, images, setup, timings, derivatives=False)
        return (found, summary, final, setup,
                self.silhouette_loss.check(greys, found, predicted, colours=frames), moved)

    def _frame_setup(self, predicted: np.ndarray, timings: dict[str, float]) -> dict:
        """Planes, pixel points and visibility orders at the predicted state."""
        tic = time.perf_counter()
        kin = forward_kinematics(self.model, predicted)
        planes = [t.planes(kin, cam) for t, cam in zip(self.templates, self.rig, strict=True)]
        points = [t.shape_points(p) for t, p in zip(self.templates, planes, strict=True)]
        timings["template_rendering"] += time.perf_counter() - tic
        tic = time.perf_counter()
        orders, events, regions, all_windows = [], [], [], []
        for c, cam in enumerate(self.rig):
            windows = image_windows(self.parts, planes[c], kin, cam)
            all_windows.append(windows)
            if self.backgrounds:
                regions.append(window_region(windows, self.backgrounds[c].values.shape,
                                             self.options.background_pad_px))
            order = predict_visibility(self.parts, windows, cam,
                                       self.options.templates.occlusion_margin_px,
                                       self._rig_templates.pixel_depth_at_joints)
            events.append(occlusion_events(self._orders[c], order))
            orders.append(order)
        self._orders = list(orders)
        timings["visibility"] += time.perf_counter() - tic
        return {"planes": planes, "points": points, "orders": orders, "events": events,
                "regions": regions, "windows": all_windows}

    def _filter_region(self, windows: ImageWindows) -> tuple[int, int, int, int] | None:
        """The image box to filter (``filter_pad_px`` around the windows' box), or None
        for the whole image (no pad set, or the filtered background needs it all)."""
        pad = self.options.templates.filter_pad_px
        if pad is None or self.options.background == "filtered" or not len(windows.kind):
            return None
        box = windows.bounds()
        low, high = box[:, :2].min(axis=0) - pad, box[:, 2:].max(axis=0) + pad
        if not (np.isfinite(low).all() and np.isfinite(high).all()):
            return None
        return (int(np.floor(low[0])), int(np.floor(low[1])), int(np.ceil(high[0])) + 1,
                int(np.ceil(high[1])) + 1)

    def _evaluate_all(self, q: np.ndarray, images: list[np.ndarray], setup: dict,
                      timings: dict[str, float], kin=None, derivatives: bool = True
                      ) -> list[LayeredEvaluation]:
        """The layered template error of every camera at ``q`` (the parts' twists,
        which do not depend on the camera, computed once); without ``derivatives`` the
        error, residuals and visibility alone (a solve's final state)."""
        kin = forward_kinematics(self.model, q) if kin is None else kin
        tic = time.perf_counter()
        twists = part_twists(self.parts, kin) if derivatives else None
        rig = self._rig_templates
        evaluations = [evaluate_layered(self.templates[c], images[c], self.rig[c], kin,
                                        setup["planes"][c], setup["orders"][c], rig.tau,
                                        p_shape=setup["points"][c],
                                        margin=rig.occlusion_margin_px, twists=twists,
                                        derivatives=derivatives,
                                        hidden_residual=rig.hidden_residual)
                       for c in range(len(self.rig))]
        timings["residual"] += time.perf_counter() - tic
        return evaluations

    def _background_images(self, images: list[np.ndarray], greys: list[np.ndarray]
                           ) -> list[np.ndarray]:
        """The images the background template is compared in (``background`` option)."""
        return greys if self.options.background == "grey" else images

    def _unoccluded_links(self, order: VisibilityOrder) -> list[str]:
        """Cylinder links that no part occludes in ``order``. The neighbours of a flexed
        link count: the revolute-joint rule (Sec. 3.2.2) puts one of two adjacent
        phalanges in front of the other, so a finger curling away from the camera gets
        features on few of its links (docs/templates.md, "The desk pair, measured
        closer")."""
        names = []
        for name in self._feature_links:
            link = next(i for i, lk in enumerate(self.model.links) if lk.name == name)
            k = self._part_of_link.get(link)
            if k is not None and not order.in_front(k):
                names.append(name)
        return names

    def _solve(self, q0: np.ndarray, images, greys, setup: dict,
               timings: dict[str, float]) -> tuple[np.ndarray, SolverSummary]:
        opts = self.options
        summary = SolverSummary()
        q = q0
        weight = opts.template_weight
        for iteration in range(opts.iterations_per_frame):
            kin = forward_kinematics(self.model, q)
            H = np.zeros((self.model.n_v, self.model.n_v))
            g = np.zeros(self.model.n_v)
            energy = 0.0
            for c, ev in enumerate(self._evaluate_all(q, images, setup, timings, kin)):
                tic = time.perf_counter()
                H += weight * ev.H
                g += weight * ev.gradient
                energy += weight * ev.energy
                timings["jacobian"] += time.perf_counter() - tic
                if self.backgrounds:
                    tic = time.perf_counter()
                    bg = evaluate_background(self.backgrounds[c],
                                             self._background_images(images, greys)[c],
                                             ev.windows, opts.templates.tau,
                                             opts.templates.occlusion_margin_px,
                                             setup["regions"][c])
                    g += opts.background_weight * weight * bg.gradient
                    energy += opts.background_weight * weight * bg.energy
                    timings["residual"] += time.perf_counter() - tic
            if opts.edge_features:
                tic = time.perf_counter()
                for c, cam in enumerate(self.rig):
                    links = self._unoccluded_links(setup["orders"][c])
                    if not links:
                        continue
                    meas = measure_features(greys[c], cam, self.model, kin, opts.features,
                                            links, [])
                    r, J, _ = feature_residuals(meas, cam, kin, jacobian=True)
                    H += opts.feature_weight * (J.T @ J)
                    g += opts.feature_weight * (J.T @ r)
                    energy += 0.5 * opts.feature_weight * float(r @ r)
                timings["features"] += time.perf_counter() - tic
            if iteration == 0:
                summary.cost_initial = energy
            summary.cost_history.append(energy)
            tic = time.perf_counter()
            if opts.solver == "gauss-newton":
                dv, truncated = solve_normal_equations(H + np.diag(self.S), g)
                summary.n_pseudo_inverse += truncated
                dv = -dv
            else:
                dv = -opts.step_size * g
            if not np.isfinite(dv).all():
                summary.termination = "singular"
                timings["linear_solve"] += time.perf_counter() - tic
                break
            q = self.parameterisation.project(self.parameterisation.retract(q, dv))
            summary.iterations += 1
            summary.step_norms.append(float(np.linalg.norm(dv)))
            timings["linear_solve"] += time.perf_counter() - tic
        summary.termination = summary.termination or "max_iterations"
        return q, summary

    def _result(self, q, kin: Kinematics, predicted, summary: SolverSummary,
                final: list[LayeredEvaluation], setup: dict, timings: dict[str, float],
                verdict: SilhouetteVerdict | None) -> TrackResult:
        """The frame's result at the solved state ``q`` (``kin`` its forward kinematics),
        and the template refresh when the residual rules pass."""
        opts = self.options
        energy = sum(ev.energy for ev in final) * opts.template_weight
        summary.cost_final = energy
        summary.n_residuals = int(sum(len(ev.residuals) for ev in final))
        weight_sum = sum(float(ev.visibility.sum()) for ev in final)
        rms = float(np.sqrt(sum(float((ev.visibility * ev.residuals ** 2).sum())
                                for ev in final) / weight_sum)) if weight_sum > 0 else np.nan
        acquired = sum(float(t.weights.sum()) for t in self.templates)
        visible_fraction = weight_sum / acquired if acquired > 0 else 0.0
        residual_reasons = self._loss_reasons(rms, visible_fraction)
        if np.isfinite(rms):
            self._rms_history.append(rms)
        refreshed = 0
        if not residual_reasons:
            tic = time.perf_counter()
            refreshed = sum(refresh_templates(t, ev, self._rig_templates, kin, cam)
                            for t, ev, cam in zip(self.templates, final, self.rig, strict=True))
            timings["refresh"] = time.perf_counter() - tic
        feature_links = ([self._unoccluded_links(o) for o in setup["orders"]]
                         if opts.edge_features else [[] for _ in self.rig])
        finger_rms = self._finger_rms(final)
        details = TemplateDetails(
            list(self.templates), setup["orders"], setup["events"], final, setup["planes"],
            [(cam.width, cam.height) for cam in self.rig], visible_fraction, rms,
            feature_links, refreshed, summary, finger_rms, bool(residual_reasons))
        reasons = residual_reasons + (verdict.reasons if verdict else [])
        finger_lost = {f: bool(v > opts.max_residual_rms) for f, v in finger_rms.items()}
        for finger, lost in (verdict.finger_lost if verdict else {}).items():
            finger_lost[finger] = finger_lost.get(finger, False) or lost
        return TrackResult(
            state=q, cost=energy, residual_rms_px=rms, lost=bool(reasons),
            loss_reason="; ".join(reasons), iterations=summary.iterations,
            predicted_state=predicted, frame_index=self._frame_index, timings=timings,
            finger_lost=finger_lost, details=details,
            hand_scale=self.sizing.hand_scale)

    def _finger_rms(self, final: list[LayeredEvaluation]) -> dict[str, float]:
        """Visibility-weighted residual RMS of each finger's parts over all cameras."""
        squares = dict.fromkeys(self._fingers, 0.0)
        weights = dict.fromkeys(self._fingers, 0.0)
        for t, ev in zip(self.templates, final, strict=True):
            for finger, parts in self._fingers.items():
                for k in parts:
                    sl = t.slices[k]
                    v = ev.visibility[sl]
                    squares[finger] += float((v * ev.residuals[sl] ** 2).sum())
                    weights[finger] += float(v.sum())
        return {f: float(np.sqrt(squares[f] / weights[f])) if weights[f] > 0 else np.nan
                for f in self._fingers}

    def _loss_reasons(self, rms: float, visible_fraction: float) -> list[str]:
        opts = self.options
        if not np.isfinite(rms):
            return ["no template pixel visible"]
        reasons = []
        if rms > opts.max_residual_rms:
            reasons.append(f"template residual RMS {rms:.1f} > {opts.max_residual_rms:.1f}")
        if visible_fraction < opts.min_visible_fraction:
            reasons.append(f"only {visible_fraction:.0%} of the template pixels visible")
        k = opts.growth_frames
        if len(self._rms_history) >= k:
            values = np.append(np.asarray(self._rms_history, dtype=float)[-k:], rms)
            if (np.all(np.diff(values) > 0) and rms > opts.growth_factor * values[0]
                    and rms > opts.growth_min):
                reasons.append(f"template residual RMS grew from {values[0]:.1f} to "
                               f"{rms:.1f} over {k} frames")
        return reasons


class LayeredFeatureTracker(LayeredTemplateTracker):
    """Layered templates everywhere plus the DigitEyes edge features (thesis Sec. 2.5) of
    the links that no other part occludes, in one least-squares system. Registered as
    tracker ``"templates+features"`` (``edge_features`` is always on)."""

    def __init__(self, model: KinematicModel, rig: Rig,
                 options: LayeredTemplateOptions | None = None) -> None:
        options = LayeredTemplateOptions() if options is None else options
        if not options.edge_features:
            options = LayeredTemplateOptions(**{**options.__dict__, "edge_features": True})
        super().__init__(model, rig, options)
