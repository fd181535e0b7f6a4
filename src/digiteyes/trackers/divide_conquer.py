"""Divide and conquer (Huang, Wu & Lin): palm by ICP and factorisation, fingers by
sequential Monte Carlo in the PCA configuration space, alternated per frame (Sec. 3).

Each frame: draw finger hypotheses from the particle set (the sampler: Huang's manifold
proposal, eq. 3-5, or a baseline of Sec. 6), then alternate EM-fashion

1. palm pose by ICP of the palm outline against the frame's edges with the fingers held at
   the best hypothesis (Sec. 4; outline points hidden by fingers are left out); the new
   pose is kept only if the best hypothesis's likelihood does not drop (an M-step must not
   lower the objective), otherwise the alternation stops;
2. finger weights (eq. 6, likelihood of Sec. 5.2) with the palm held at that pose;

until the palm moves less than ``em_tolerance_mm`` (and ``em_tolerance_deg``) or after
``em_iterations`` rounds. Then ``refine_rounds`` times: the digit-by-digit search
(:mod:`digiteyes.smc.digit_search`, ours: each digit moved along its curl, the palm
held) and the palm refinement (:mod:`digiteyes.smc.palm_search`, the fingers held), both
on the best hypothesis, which they replace. The best-weighted hypothesis is the
estimate; the set is then resampled (systematic, from the tracker's Generator) for the
next frame.

Three samplers share everything else (same likelihood, same palm step):
:class:`DivideConquerTracker` (``"manifold"``, 300 particles by default),
:class:`CondensationTracker` (``"condensation"``: random-walk dynamics, weights = the
likelihood, 3000 particles) and :class:`RandomSearchTracker` (``"random-search"``: 5000
samples around the last estimate, the best one kept, no particle set).

Track loss: a frame is ``lost`` when fewer than ``min_edge_fraction`` of the best
hypothesis's visible finger sample points find an edge, or (``silhouette_check``, a
plain backdrop) by the silhouette rule of the feature tracker
(:mod:`digiteyes.trackers.silhouette_loss`, the same thresholds), which also names the
fingers in ``finger_lost``. The edge likelihood stays high when a finger hypothesis lies
on the edges of the palm or a neighbour (docs/accuracy.md). Loss is reported, not acted
on.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from digiteyes.camera import Camera, Rig
from digiteyes.errors import DigitEyesError
from digiteyes.features.slices import prepare_image
from digiteyes.kinematics import KinematicModel
from digiteyes.kinematics.anatomy import DIGITS
from digiteyes.kinematics.state import validate_state
from digiteyes.smc.configuration import ConfigurationSpace
from digiteyes.smc.digit_resampling import best_of_each_digit, digit_of, digit_resample
from digiteyes.smc.digit_search import DigitSearchOptions, digit_curl_directions, search_digits
from digiteyes.smc.likelihood import (
    EdgeLookup,
    FingerGeometry,
    LikelihoodOptions,
    LikelihoodResult,
    edge_lookup,
    finger_log_likelihood,
    fit_finger_width,
    observe_edges,
)
from digiteyes.smc.manifolds import manifold_pairs
from digiteyes.smc.palm import (
    IcpOptions,
    OutlineCalibration,
    PalmPoseError,
    calibrate_palm_outline,
    calibrate_palm_scale,
    icp_palm,
    nearest_edge_field,
    outline_visibility,
    palm_outline_points,
    palm_pose_from_state,
    with_palm_pose,
)
from digiteyes.smc.palm_search import (
    PalmSearchOptions,
    outline_edge_fraction,
    outline_log_score,
    palm_outline_samples,
    perturbed_palms,
    search_palm_pose,
)
from digiteyes.smc.prior import default_configuration_space
from digiteyes.smc.proposal import (
    ProposalOptions,
    importance_log_weights,
    propose_on_manifolds,
    random_walk_log_prior,
)
from digiteyes.smc.resample import effective_sample_size, normalised_weights, systematic_resample
from digiteyes.smc.spread import SpreadHeldSpace
from digiteyes.trackers.base import TrackResult
from digiteyes.trackers.feature_size import StartSize
from digiteyes.trackers.loss_hold import LossHold, LossHoldOptions
from digiteyes.trackers.silhouette_loss import (
    SilhouetteLoss,
    SilhouetteLossOptions,
)

SAMPLERS = ("manifold", "condensation", "random-search")
OVERLAY_SAMPLE = 24
"""Hypotheses kept in :attr:`DivideConquerDetails.sample_states` for the overlay."""


@dataclass(frozen=True)
class DivideConquerOptions(SilhouetteLossOptions, LossHoldOptions):
    """Settings of the divide-and-conquer tracker and its baselines.

    sampler : ``"manifold"`` (Huang Sec. 5.1), ``"condensation"`` or ``"random-search"``.
    n_particles : hypotheses per frame.
    em_iterations, em_tolerance_mm, em_tolerance_deg : the EM stop rule (Sec. 3).
    palm_motion_mm, palm_motion_deg : a motion prior on the palm in the EM's M-step (ours):
        standard deviations, per frame, of the palm's move along the first camera's line
        of sight (mm) and of its rotation (degrees) from the frame's prediction; a palm
        step is kept when it does not lower the best hypothesis's log weight (eq. 6)
        minus the prior's ``(dz / palm_motion_mm)^2 / 2 + (angle / palm_motion_deg)^2 / 2``
        (0 turns a term off). At 30 frames/s the defaults are 0.9 m/s and 300 degrees/s:
        they leave a hand's motion free and refuse the jumps of a palm that three sides
        of its outline fit as well farther away and tilted where the fingers gain little
        by them (docs/divide-and-conquer.md).
    track_palm : run the palm step (off: the palm stays at the reset pose).
    importance_correction : multiply by ``f / g`` (eq. 6); off, weights = likelihood.
    temperature : the log-likelihood is divided by it in the weights (1: Huang's weights;
        above 1 flattens them and keeps the particle set diverse).
    condensation_sigma : random-walk std of the CONDENSATION dynamics, PCA units.
    search_sigma : std of the random search around the last estimate, PCA units.
    walk_fraction : share of the manifold sampler's particles drawn instead by the
        CONDENSATION random walk (``condensation_sigma``) from their parent, so that the
        set can follow motion off the manifolds (weights: ``f / g`` with ``g`` that walk).
    anneal_layers : extra layers per frame (annealed particle filter): resample by the
        weights, perturb by a random walk half as wide as the last, reweight.
    min_edge_fraction : the track is reported lost when fewer visible sample points than
        this fraction find an edge.
    silhouette_check, silhouette_tolerance_px, max_unexplained, max_finger_outside : the
        silhouette loss rule (:class:`~digiteyes.trackers.silhouette_loss.SilhouetteLoss`;
        defaults as the feature tracker's).
    hold_lost_frames : after a frame the loss rules call lost, later frames stay lost
        until this many in a row have passed them
        (:class:`~digiteyes.trackers.loss_hold.LossHold`; 0, the default, judges each
        frame alone: a particle filter can find a finger again by itself).
    refine_rounds : rounds of digit search then palm refinement after the EM rounds.
    digit_resampling : split each hypothesis's likelihood into its five digits' shares;
        start the digit search from the hypothesis made of each digit's best-explained
        joints when it beats the best whole one
        (:func:`~digiteyes.smc.digit_resampling.best_of_each_digit`), and resample each
        digit's joints by its own share instead of whole particles by the whole
        likelihood, the frame's estimate kept as one of the particles
        (:func:`~digiteyes.smc.digit_resampling.digit_resample`). Ours,
        docs/divide-and-conquer.md, "Per-digit resampling"; off in the baselines'
        options and in Huang's tracker alone.
    hold_start_spread : carry the start state's finger spread that the configuration
        space cannot express, scaled by each finger's openness
        (:class:`~digiteyes.smc.spread.SpreadHeldSpace`), whatever the first frame shows.
    spread_test_margin : when ``hold_start_spread`` is off, hold the start's spread all
        the same if, on the first frame (and on the first after each
        :meth:`DivideConquerTracker.restart`, for its own start), the start with its
        spread held explains the image better than the start as the space reconstructs
        it by more than this many units of log-likelihood (eq. 6's ``log p(Z | X)``; 10
        is a likelihood ratio of e^10): a start whose spread the space cannot express
        (the accuracy table's setups) keeps it, while a start inside the space
        (``natural``) or a wrong one (the recovery runs' 30 degrees off) does not. None
        never holds it. Ours, docs/divide-and-conquer.md, "Known limits"; off in the
        baselines' options.
    fit_first_frame : fit the model's patches to the user's hand on the first frame, at
        the state the track starts from: the palm outline's sides
        (:func:`~digiteyes.smc.palm.calibrate_palm_outline`; the outline serves the ICP,
        the outline term and the occlusion map) and the fingers' width
        (:func:`~digiteyes.smc.likelihood.fit_finger_width`).
    digit_search : the digit-by-digit search (:mod:`digiteyes.smc.digit_search`;
        ``passes=0`` turns it off: Huang's tracker alone). Off in the baselines' options
        (:class:`CondensationOptions`, :class:`RandomSearchOptions`), as Huang runs them.
    palm_search : the palm refinement after the EM rounds (:mod:`digiteyes.smc.palm_search`;
        ``rounds=0`` turns it off).
    proposal, likelihood, icp : options of the parts.
    seed : seed of the tracker's Generator (every draw comes from it).
    start_size : on the first frame, before the patches are fitted, measure the hand's
        size at the start state from the feature tracker's line and tip features
        (:func:`~digiteyes.trackers.feature_size.hand_size_at`) and track a model of that
        size; the start must be the hand's pose (``digiteyes track`` turns it off for a
        start fitted from the images or placed by eye on footage). Results carry the size
        as :attr:`~digiteyes.trackers.TrackResult.hand_scale`.
    """

    sampler: str = "manifold"
    n_particles: int = 300
    em_iterations: int = 3
    em_tolerance_mm: float = 0.5
    em_tolerance_deg: float = 0.5
    palm_motion_mm: float = 30.0
    palm_motion_deg: float = 10.0
    track_palm: bool = True
    importance_correction: bool = True
    temperature: float = 1.0
    condensation_sigma: float = 0.08
    search_sigma: float = 0.15
    walk_fraction: float = 0.1
    digit_resampling: bool = True
    refine_rounds: int = 1
    fit_first_frame: bool = True
    hold_start_spread: bool = False
    spread_test_margin: float | None = 10.0
    anneal_layers: int = 0
    min_edge_fraction: float = 0.3
    proposal: ProposalOptions = field(default_factory=ProposalOptions)
    likelihood: LikelihoodOptions = field(default_factory=LikelihoodOptions)
    icp: IcpOptions = field(default_factory=IcpOptions)
    palm_search: PalmSearchOptions = field(default_factory=PalmSearchOptions)
    digit_search: DigitSearchOptions = field(default_factory=DigitSearchOptions)
    seed: int = 0
    start_size: bool = True

    def __post_init__(self) -> None:
        for name in ("palm_motion_mm", "palm_motion_deg"):
            if not getattr(self, name) >= 0:
                raise DigitEyesError(f"{name} must be >= 0 (0: off), got "
                                     f"{getattr(self, name)!r}")


@dataclass
class DivideConquerDetails:
    """Tracker-specific outputs of one frame.

    particles : (N, D) hypotheses in PCA coordinates (before resampling).
    weights : (N,) their normalised weights.
    best_coordinates : (D,) the chosen hypothesis; best_index : its row in ``particles``.
    log_likelihood : (N,) ``log p(Z | X)`` of every hypothesis.
    effective_sample_size : ``1 / sum w^2``.
    palm_model_points : (P, 3) palm outline points used (palm frame, mm).
    palm_pixels : (P, 2) their matched edge pixels; palm_rms_px : reprojection RMS.
    em_rounds : palm/finger alternations done; em_stop : why they stopped.
    sample_states : (S, n_q) full states of a sample of the hypotheses (S at most
        ``OVERLAY_SAMPLE``, at evenly spaced weight ranks from the best), for drawing.
    """

    particles: np.ndarray
    weights: np.ndarray
    best_coordinates: np.ndarray
    best_index: int
    log_likelihood: np.ndarray
    effective_sample_size: float
    palm_model_points: np.ndarray
    palm_pixels: np.ndarray
    palm_rms_px: float
    em_rounds: int
    em_stop: str
    sample_states: np.ndarray


@dataclass(frozen=True)
class CondensationOptions(DivideConquerOptions):
    """:class:`DivideConquerOptions` with the CONDENSATION baseline's defaults (Huang
    Sec. 6: 3000 samples, random-walk dynamics, no digit search)."""

    sampler: str = "condensation"
    n_particles: int = 3000
    digit_resampling: bool = False
    spread_test_margin: float | None = None
    digit_search: DigitSearchOptions = field(
        default_factory=lambda: DigitSearchOptions(passes=0))


@dataclass(frozen=True)
class RandomSearchOptions(DivideConquerOptions):
    """:class:`DivideConquerOptions` with the random-search baseline's defaults (Huang
    Sec. 6: 5000 samples per frame around the last estimate, no digit search)."""

    sampler: str = "random-search"
    n_particles: int = 5000
    digit_resampling: bool = False
    spread_test_margin: float | None = None
    digit_search: DigitSearchOptions = field(
        default_factory=lambda: DigitSearchOptions(passes=0))


def _as_rig(rig: Rig | Camera | Sequence[Camera]) -> Rig:
    if isinstance(rig, Rig):
        return rig
    if isinstance(rig, Camera):
        return Rig((rig,))
    cams = tuple(rig)
    if not cams:
        raise DigitEyesError("the tracker needs at least one camera")
    return Rig(cams)


def _rotation_deg(Ra: np.ndarray, Rb: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(Ra.T @ Rb) - 1) / 2, -1.0, 1.0))))


class DivideConquerTracker:
    """Huang, Wu & Lin's tracker (Sec. 3-5) behind the :class:`Tracker` protocol.

    Parameters
    ----------
    model : ``cardboard-hand`` or ``hand`` (any model with a root pose, a palm box and
        finger links).
    rig : cameras (a :class:`Rig`, or one camera or a list of them); the palm step uses
        the first, the likelihood all of them.
    options : :class:`DivideConquerOptions` (default: :attr:`options_type` ()).
    space : the configuration space (default: :func:`default_configuration_space`).
    """

    stages = ("edges", "proposal", "palm_icp", "likelihood", "digit_search", "resampling",
              "silhouette")
    """Timing stages of :attr:`TrackResult.timings` (``silhouette``: the silhouette loss
    rule)."""
    options_type: type[DivideConquerOptions] = DivideConquerOptions

    def __init__(self, model: KinematicModel, rig: Rig | Camera | Sequence[Camera],
                 options: DivideConquerOptions | None = None,
                 space: ConfigurationSpace | None = None) -> None:
        if options is None:
            options = self.options_type()
        if options.sampler not in SAMPLERS:
            raise DigitEyesError(f"sampler must be one of {', '.join(SAMPLERS)}, got "
                                 f"{options.sampler!r}")
        if model.base_state is None:
            raise DigitEyesError(f"model {model.name!r} has no palm pose (pose:q row)")
        self.rig, self.options = _as_rig(rig), options
        self.sizing = StartSize(model, options.start_size)
        self.cameras = self.rig.cameras
        self.space = self.base_space = space or default_configuration_space(model)
        self.joint_index = self.space.joint_indices(model)
        self._build(model)
        self.pairs = manifold_pairs(len(self.space.basis))
        self.curl_directions = digit_curl_directions(self.space)
        self.palm_scale = 1.0
        self.rng = np.random.default_rng(options.seed)
        self.state: np.ndarray | None = None
        self.particles = np.zeros((0, self.space.n_dims))
        self.frame_index = -1
        self.loss_hold = LossHold(options.hold_lost_frames)
        self.palm_search_options = options.palm_search
        self.outline_fit: float | None = None
        self.outline_calibration: OutlineCalibration | None = None
        self.finger_width_scale = 1.0
        self.spread_test: tuple[float, float] | None = None
        """The log-likelihoods, on the first frame of the track or after its last
        restart, of the start as the space reconstructs it and with its spread held
        (``spread_test_margin``; None before it or when off)."""

    @property
    def scale(self) -> float | None:
        """The size of the tracked hand relative to the model file (``start_size``; None
        when the tracker does not size the hand)."""
        return self.sizing.scale

    def _build(self, model: KinematicModel) -> None:
        """What depends on the tracked model (the model file's or the measured size's):
        the patch geometry and the silhouette rule."""
        self.model = model
        self.geometry = self.model_geometry = FingerGeometry.of(model)
        if self.options.digit_resampling:
            # (L, 5): sums each patch's likelihood terms into its digit's
            self.digit_of_link = np.eye(len(DIGITS))[digit_of(self.geometry.link_names)]
        self.silhouette_loss = SilhouetteLoss.from_options(model, self.rig, self.options)

    # ------------------------------------------------------------------ protocol
    def reset(self, initial_state: np.ndarray) -> None:
        """Start a track at ``initial_state`` (n_q,): palm pose and finger joints."""
        q = np.asarray(initial_state, dtype=float)
        if (model := self.sizing.forget()) is not None:  # a new track: size unknown again
            self._build(model)
        if q.shape != (self.model.n_q,):
            raise DigitEyesError(f"initial state must have shape ({self.model.n_q},), got "
                                 f"{q.shape}")
        self.state = q.copy()
        self.space = (SpreadHeldSpace.of(self.base_space, q[self.joint_index])
                      if self.options.hold_start_spread else self.base_space)
        self.spread_test = None
        self._particles_at(q)
        self.rng = np.random.default_rng(self.options.seed)
        self.frame_index = -1
        self.silhouette_loss.reset()
        self.loss_hold.reset()
        self.palm_search_options = self.options.palm_search
        self.outline_fit = None
        self.outline_calibration = None
        self.finger_width_scale = 1.0
        self.geometry = self.model_geometry

    def restart(self, state: np.ndarray) -> None:
        """Continue the same scene from ``state`` (n_q,) after a re-detection: the
        particles start again at ``state`` and the silhouette baselines are taken anew
        there, but the hand's size, the palm outline and finger widths fitted on the first
        frame, the outline check and the silhouette rule's foreground stay. A re-detected
        pose is coarser than the start they were fitted at: fitted again there, the
        foreground failed to split the real video's frames and the loss rule went quiet
        for the rest of the run (docs/divide-and-conquer.md). The start's spread is tested
        again on the next frame (``spread_test_margin``): it is the new start's."""
        self.state = validate_state(self.model, np.asarray(state, dtype=float),
                                    normalize=True)
        if not self.options.hold_start_spread:  # the new start's spread is tested afresh
            self.space, self.spread_test = self.base_space, None
        self._particles_at(self.state)
        self.silhouette_loss.rebaseline()
        self.loss_hold.reset()

    def _particles_at(self, q: np.ndarray) -> None:
        """Every particle at the finger configuration of state ``q`` (n_q,)."""
        X0 = self.space.to_coordinates(q[self.joint_index])
        self.particles = np.repeat(X0[None], self.options.n_particles, axis=0)

    def calibrate(self, frame: np.ndarray, state: np.ndarray) -> float:
        """Palm size from a frame of the open palm at a known ``state`` (Huang Sec. 4.2);
        stores and returns the outline scale."""
        edges = observe_edges(frame, self.options.likelihood)
        self.palm_scale = calibrate_palm_scale(self.model, self.geometry, state,
                                               self.cameras[0], nearest_edge_field(edges),
                                               options=self.options.icp)
        return self.palm_scale

    def step(self, frames: Sequence[np.ndarray]) -> TrackResult:
        """Track one set of frames (one image per camera, in rig order)."""
        if self.state is None:
            raise DigitEyesError("call reset(initial_state) before step()")
        self.rig.check_images(frames)
        t_start = time.perf_counter()
        timings = dict.fromkeys((*self.stages, "total"), 0.0)
        opt = self.options
        self.frame_index += 1
        t = time.perf_counter()
        # the hand's size, on the first frame before the patches are fitted to the hand
        if (model := self.sizing.measure(self.rig, frames, self.state)) is not None:
            self._build(model)
        edge_maps = [observe_edges(f, opt.likelihood) for f in frames]
        lookups = [edge_lookup(e, opt.likelihood) for e in edge_maps]
        nearest = nearest_edge_field(edge_maps[0]) if opt.track_palm else None
        if self.frame_index == 0 and opt.track_palm:
            self._fit_first_frame(edge_maps, lookups)
        if self.spread_test is None:  # a new start (cheap when the test is off)
            self._test_start_spread(edge_maps, lookups)
        timings["edges"] = time.perf_counter() - t

        t = time.perf_counter()
        X, log_fg = self._draw()
        timings["proposal"] = time.perf_counter() - t
        predicted = self.state.copy()
        q = predicted.copy()

        def weigh(q_palm: np.ndarray):
            """E-step: ``log p(Z | X)`` and log weights (eq. 6) with the palm at ``q_palm``."""
            t0 = time.perf_counter()
            result = finger_log_likelihood(self.model, self.geometry,
                                           self.space.states(self.model, q_palm, X),
                                           self.cameras, edge_maps, opt.likelihood,
                                           lookups, per_link=opt.digit_resampling)
            log_weights = result.log_likelihood / opt.temperature + (
                log_fg if opt.importance_correction else 0.0)
            timings["likelihood"] += time.perf_counter() - t0
            return result, log_weights

        lik, log_w = weigh(q)
        sigma = opt.condensation_sigma
        for _ in range(opt.anneal_layers):
            t = time.perf_counter()
            sigma *= 0.5
            parents = systematic_resample(normalised_weights(log_w), self.rng, len(X))
            X = X[parents] + sigma * self.rng.standard_normal(X[parents].shape)
            log_fg = np.zeros(len(X))
            timings["proposal"] += time.perf_counter() - t
            lik, log_w = weigh(q)
        best = int(np.argmax(log_w))
        palm_points, palm_pixels, palm_rms = np.zeros((0, 3)), np.zeros((0, 2)), np.nan
        stop, rounds = "max_iterations", 0
        cost = self._palm_motion_cost(q, predicted)  # the motion prior at the palm kept
        while rounds < opt.em_iterations:
            rounds += 1
            if not opt.track_palm:
                stop = "palm fixed"
                break
            t = time.perf_counter()
            q_fingers = self.space.states(self.model, q, X[best])[0]
            T_before = palm_pose_from_state(self.model, q)
            try:
                pts = palm_outline_points(self.geometry, opt.icp, self.palm_scale)
                visible = outline_visibility(self.model, self.geometry, q_fingers,
                                             self.cameras[0], pts)
                fit = icp_palm(self.model, self.geometry, q_fingers, self.cameras[0],
                               nearest, opt.icp, self.palm_scale, visible)
            except PalmPoseError:
                stop = "palm: too few correspondences"
                timings["palm_icp"] += time.perf_counter() - t
                break
            timings["palm_icp"] += time.perf_counter() - t
            q_new = with_palm_pose(self.model, q, fit.T_world_palm)
            lik_new, log_w_new = weigh(q_new)
            # An M-step must not lower the objective: keep the new palm only if the best
            # hypothesis under it is weighted at least as well as before, with the palm's
            # motion prior (MAP rather than maximum-likelihood EM).
            cost_new = self._palm_motion_cost(q_new, predicted)
            if log_w_new.max() - cost_new < log_w.max() - cost:
                stop = "palm step rejected"
                break
            q, lik, log_w, cost = q_new, lik_new, log_w_new, cost_new
            best = int(np.argmax(log_w))
            palm_points, palm_pixels, palm_rms = fit.model_points, fit.pixels, fit.rms_px
            if (np.linalg.norm(fit.T_world_palm[:3, 3] - T_before[:3, 3]) < opt.em_tolerance_mm
                    and _rotation_deg(fit.T_world_palm[:3, :3], T_before[:3, :3])
                    < opt.em_tolerance_deg):
                stop = "converged"
                break
        x_best, changed = X[best], False
        if opt.digit_resampling:
            x_best, changed = self._best_of_each_digit(X, best, lik, q, edge_maps, lookups)
        for _ in range(opt.refine_rounds):
            if opt.digit_search.passes > 0:
                t = time.perf_counter()
                x_best, q, moved = self._search_digits(x_best, q, edge_maps, lookups)
                changed = changed or moved
                timings["digit_search"] += time.perf_counter() - t
            if opt.track_palm and opt.palm_search.rounds > 0:
                t = time.perf_counter()
                q_new, new_score, old_score = search_palm_pose(
                    self.model, self.geometry, self.space.states(self.model, q, x_best)[0],
                    self.cameras, edge_maps, lookups, self.rng, self.palm_search_options,
                    opt.likelihood)
                timings["palm_icp"] += time.perf_counter() - t
                if new_score > old_score:
                    i = self.model.base_state
                    q = q.copy()
                    q[i:i + 7] = q_new[i:i + 7]
                    changed = True
        if changed:
            X = X.copy()
            X[best] = x_best
            lik, log_w = weigh(q)
            best = int(np.argmax(log_w))
        weights = normalised_weights(log_w)

        t = time.perf_counter()
        if opt.sampler == "random-search":
            self.particles = X[best][None]
        elif opt.digit_resampling:
            self.particles = digit_resample(self.space, X, self.digit_log_likelihoods(lik),
                                            self.rng, opt.n_particles, opt.temperature)
            self.particles[-1] = X[best]
        else:
            self.particles = X[systematic_resample(weights, self.rng, opt.n_particles)]
        timings["resampling"] = time.perf_counter() - t

        q = self.space.states(self.model, q, X[best])[0]
        self.state = q
        visible, hits = lik.visible[best], lik.with_edge[best]
        reasons = [f"only {int(hits)} of {int(visible)} finger sample points found an edge"] \
            if visible == 0 or hits < opt.min_edge_fraction * visible else []
        finger_lost: dict[str, bool] = {}
        if opt.silhouette_check:
            t = time.perf_counter()
            verdict = self.silhouette_loss.check([prepare_image(f) for f in frames], q,
                                                 predicted, colours=frames)
            reasons += verdict.reasons
            finger_lost = verdict.finger_lost
            timings["silhouette"] = time.perf_counter() - t
        timings["total"] = time.perf_counter() - t_start
        cost = float(-lik.log_likelihood[best])
        ranks = np.argsort(-weights, kind="stable")
        shown = ranks[np.unique(np.linspace(0, len(X) - 1, min(OVERLAY_SAMPLE, len(X)))
                                .astype(int))]
        details = DivideConquerDetails(X, weights, X[best].copy(), best, lik.log_likelihood,
                                       effective_sample_size(weights), palm_points,
                                       palm_pixels, palm_rms, rounds, stop,
                                       self.space.states(self.model, q, X[shown]))
        return self.loss_hold.apply(TrackResult(
            state=q.copy(), residual_rms_px=float(lik.rms_px[best]), cost=cost,
            lost=bool(reasons), loss_reason="; ".join(reasons), iterations=rounds,
            predicted_state=predicted, frame_index=self.frame_index, timings=timings,
            finger_lost=finger_lost, details=details,
            hand_scale=self.sizing.hand_scale))

    def _best_of_each_digit(self, X: np.ndarray, best: int, lik: LikelihoodResult,
                            q: np.ndarray, edge_maps: list[np.ndarray],
                            lookups: list[EdgeLookup]) -> tuple[np.ndarray, bool]:
        """The hypothesis made of each digit's best-explained joints among ``X`` (N, D)
        (:func:`~digiteyes.smc.digit_resampling.best_of_each_digit`) when its likelihood
        under the palm of ``q`` beats that of the best whole hypothesis ``X[best]``, else
        ``X[best]``; and whether it was taken."""
        opt = self.options
        mixed = best_of_each_digit(self.space, X, self.digit_log_likelihoods(lik))
        score = finger_log_likelihood(self.model, self.geometry,
                                      self.space.states(self.model, q, mixed), self.cameras,
                                      edge_maps, opt.likelihood, lookups).log_likelihood[0]
        return (mixed, True) if score > lik.log_likelihood[best] else (X[best], False)

    def digit_log_likelihoods(self, lik: LikelihoodResult) -> np.ndarray:
        """Each hypothesis's ``log p(Z | X)`` split by digit (N, 5), thumb to little:
        the sum of its patches' terms (the likelihood's ``per_link``)."""
        return lik.per_link @ self.digit_of_link

    def _palm_motion_cost(self, q: np.ndarray, predicted: np.ndarray) -> float:
        """Negative log of the palm's motion prior (:class:`DivideConquerOptions`,
        ``palm_motion_mm`` and ``palm_motion_deg``) at state ``q`` against ``predicted``."""
        opt = self.options
        T, T_predicted = (palm_pose_from_state(self.model, x) for x in (q, predicted))
        cost = 0.0
        if opt.palm_motion_mm > 0:
            camera = self.cameras[0]
            along = camera.T_cam_world[2, :3] @ (T[:3, 3] - T_predicted[:3, 3])
            cost += 0.5 * (along / opt.palm_motion_mm) ** 2
        if opt.palm_motion_deg > 0:
            turn = _rotation_deg(T[:3, :3], T_predicted[:3, :3])
            cost += 0.5 * (turn / opt.palm_motion_deg) ** 2
        return float(cost)

    # ------------------------------------------------------------------ refinement
    def _fit_first_frame(self, edge_maps: list[np.ndarray], lookups: list[EdgeLookup]
                         ) -> None:
        """On the first frame, at the state the track starts from (``fit_first_frame``):
        fit the palm outline's sides to the user's palm
        (:func:`~digiteyes.smc.palm.calibrate_palm_outline`; kept in
        :attr:`outline_calibration`) and the fingers' width
        (:func:`~digiteyes.smc.likelihood.fit_finger_width`; kept in
        :attr:`finger_width_scale`); then keep the outline's edge term only if enough of
        the outline lies on edges (:class:`PalmSearchOptions`; the fraction is kept in
        :attr:`outline_fit`)."""
        lookup = lookups[0]
        if self.options.fit_first_frame:
            self.outline_calibration = calibrate_palm_outline(
                self.model, self.geometry, self.state, self.cameras[0], lookup)
            self.finger_width_scale = fit_finger_width(
                self.model, self.geometry, self.state, self.cameras, edge_maps,
                options=self.options.likelihood, lookups=lookups)
            self.geometry = replace(self.geometry,
                                    palm_outline=self.outline_calibration.corners,
                                    radii=self.geometry.radii * self.finger_width_scale)
        options = self.options.palm_search
        points = palm_outline_samples(self.geometry, options.outline_points)
        self.outline_fit = outline_edge_fraction(self.model, self.geometry, self.state,
                                                 self.cameras[0], lookup, points,
                                                 options.outline_check_px)
        if self.outline_fit < options.outline_check_fraction:
            self.palm_search_options = replace(options, outline_points=0)

    def _test_start_spread(self, edge_maps: list[np.ndarray], lookups: list[EdgeLookup]
                           ) -> None:
        """On the first frame of a track or of a restart (``spread_test_margin``): hold
        the start's spread when the start with it held explains the frame better than
        the start the space reconstructs, by more than the margin; both log-likelihoods
        are kept in :attr:`spread_test` (reconstructed, held)."""
        margin = self.options.spread_test_margin
        if self.options.hold_start_spread or margin is None:
            return
        joints = self.state[self.joint_index]
        held = SpreadHeldSpace.of(self.base_space, joints)
        starts = np.concatenate([space.states(self.model, self.state,
                                              space.to_coordinates(joints))
                                 for space in (self.base_space, held)])
        plain, kept = finger_log_likelihood(self.model, self.geometry, starts, self.cameras,
                                            edge_maps, self.options.likelihood,
                                            lookups).log_likelihood
        self.spread_test = (float(plain), float(kept))
        if kept > plain + margin:
            self.space = held
            self._particles_at(self.state)

    def _search_digits(self, x: np.ndarray, q: np.ndarray, edge_maps: list[np.ndarray],
                       lookups: list[EdgeLookup]) -> tuple[np.ndarray, np.ndarray, bool]:
        """The digit-by-digit search (:mod:`digiteyes.smc.digit_search`) from hypothesis
        ``x`` (D,) under the palm of ``q`` and, when the palm is tracked, perturbations of
        it; scored by the finger likelihood plus the palm outline's edge term. Returns the
        hypothesis, the state carrying the chosen palm, and whether either changed."""
        opt, search = self.options, self.options.digit_search
        i = self.model.base_state
        palms = q[None]
        if opt.track_palm and search.palms > 1:
            palms = np.concatenate([palms, perturbed_palms(
                self.model, q, self.rng, search.palms - 1, search.palm_sigma_deg,
                search.palm_sigma_mm)])
        points = palm_outline_samples(self.geometry, self.palm_search_options.outline_points)
        outline = outline_log_score(self.model, self.geometry, palms, self.cameras, lookups,
                                    points)

        def score(coordinates: np.ndarray, palm: np.ndarray) -> np.ndarray:
            Q = self.space.states(self.model, q, coordinates)
            Q[:, i:i + 7] = palms[palm, i:i + 7]
            return finger_log_likelihood(self.model, self.geometry, Q, self.cameras,
                                         edge_maps, opt.likelihood, lookups
                                         ).log_likelihood + outline[palm]

        x_new, palm, new_score, old_score = search_digits(
            self.space, x, score, search, self.curl_directions, len(palms))
        if new_score <= old_score:
            return x, q, False
        return x_new, palms[palm].copy(), True

    # ------------------------------------------------------------------ samplers
    def _draw(self) -> tuple[np.ndarray, np.ndarray]:
        """Hypotheses (N, D) and ``log f - log g`` (N,) for the configured sampler."""
        opt, prev = self.options, self.particles
        if opt.sampler == "manifold":
            prop = propose_on_manifolds(prev, self.space.basis, self.rng, opt.proposal,
                                        self.pairs)
            X, log_g = prop.X.copy(), prop.log_g.copy()
            walk = self.rng.random(len(X)) < opt.walk_fraction
            if walk.any():
                step = opt.condensation_sigma * self.rng.standard_normal((walk.sum(), X.shape[1]))
                X[walk] = prev[walk] + step
                log_g[walk] = (-0.5 * np.sum((step / opt.condensation_sigma) ** 2, axis=1)
                               - X.shape[1] * np.log(opt.condensation_sigma))
            log_f = random_walk_log_prior(X, prev, opt.proposal.prior_sigma)
            return X, importance_log_weights(0.0, log_f, log_g)
        if opt.sampler == "condensation":
            X = prev + opt.condensation_sigma * self.rng.standard_normal(prev.shape)
            return X, np.zeros(len(X))
        centre = prev.mean(axis=0)
        X = centre + opt.search_sigma * self.rng.standard_normal((opt.n_particles, len(centre)))
        X[0] = centre
        return X, np.zeros(len(X))


class CondensationTracker(DivideConquerTracker):
    """Baseline of Huang Sec. 6: CONDENSATION in the PCA space, 3000 samples."""

    options_type = CondensationOptions


class RandomSearchTracker(DivideConquerTracker):
    """Baseline of Huang Sec. 6: random search in the PCA space, 5000 samples per frame."""

    options_type = RandomSearchOptions

