"""Edge likelihood of finger hypotheses (Huang Sec. 5.2) with a model occlusion map.

Each finger patch (a ``link`` of the model) is sampled at K positions along its axis; the
two laterals at each position (the axis point moved by the patch half-width along the image
normal) are searched along that normal for edge pixels within +-``search_px``. With ``M``
edge points found at offsets ``z_m`` and Poisson clutter of density ``lambda`` (edges per
pixel along the normal), each point contributes the factor

    1 + (1 / (sqrt(2 pi) sigma_e q lambda)) sum_m exp(-z_m^2 / (2 sigma_e^2))

(Huang Sec. 5.2, after Wu, Lin & Huang 2001; ``q`` is the probability that the true edge
is missed). A lateral point hidden by another patch nearer the camera, or by the palm, is
left out (factor 1): that is the occlusion map, built per hypothesis from the model.

The edges are a Canny map of the frame, computed once per frame (:func:`observe_edges`);
searching that map along normals is what makes the likelihood cheap enough for thousands
of hypotheses per frame (the feature tracker's profile search in ``digiteyes.features``
fits lines to intensity profiles, a different job). The inner loop is compiled
(``_kernels.edge_likelihood_kernel``); distortion is applied when projecting, the patch
width uses the undistorted focal length.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from digiteyes.camera import Camera
from digiteyes.errors import DigitEyesError
from digiteyes.features import prepare_image
from digiteyes.kinematics import KinematicModel, forward_kinematics
from digiteyes.smc._kernels import edge_likelihood_kernel


@dataclass(frozen=True)
class LikelihoodOptions:
    """Parameters of the edge likelihood (Huang Sec. 5.2).

    points_per_link : K, sample positions along each patch axis.
    search_px : half-length of the search along the normal, px.
    sigma_px : ``sigma_e``, spread of a true edge about the predicted lateral, px.
    clutter_density : ``lambda``, clutter edges per pixel along the normal.
    miss_probability : ``q``, probability that the true edge is not detected.
    occlusion_margin_mm : a patch hides a point only if it is this much nearer, mm.
    canny_low, canny_high : Canny thresholds on the grey image (0..255).
    blur_sigma_px : Gaussian blur before Canny, px.
    search : ``"normal"`` (default): Huang's search along the normal, every edge found
        counted; ``"distance"``: each lateral point reads a per-frame table built from the
        distance transform of the edge map (:func:`edge_lookup`): the nearest edge within
        ``search_px`` only, at its Euclidean distance (about 3 times faster, less
        accurate in tracking: see docs/divide-and-conquer.md).
    """

    points_per_link: int = 3
    search_px: int = 8
    sigma_px: float = 2.0
    clutter_density: float = 0.05
    miss_probability: float = 0.1
    occlusion_margin_mm: float = 3.0
    canny_low: float = 20.0
    canny_high: float = 60.0
    blur_sigma_px: float = 1.0
    search: str = "normal"

    def __post_init__(self) -> None:
        if self.search not in ("distance", "normal"):
            raise DigitEyesError(f"LikelihoodOptions.search must be 'distance' or 'normal', "
                                 f"got {self.search!r}")

    @property
    def inverse_clutter(self) -> float:
        """``1 / (sqrt(2 pi) sigma_e q lambda)`` of Huang Sec. 5.2."""
        return 1.0 / (np.sqrt(2 * np.pi) * self.sigma_px * self.miss_probability
                      * self.clutter_density)


def observe_edges(frame: np.ndarray, options: LikelihoodOptions = LikelihoodOptions()
                  ) -> np.ndarray:
    """Canny edge map (H, W) uint8 (255 on edges) of a grey or RGB frame."""
    grey = prepare_image(frame)
    if grey.dtype != np.uint8:
        grey = np.clip(grey, 0, 255).astype(np.uint8)
    if options.blur_sigma_px > 0:
        grey = cv2.GaussianBlur(grey, (0, 0), options.blur_sigma_px)
    return cv2.Canny(grey, options.canny_low, options.canny_high, L2gradient=True)


@dataclass(frozen=True)
class EdgeLookup:
    """Per-frame tables of the ``"distance"`` likelihood: ``distance`` (H, W) float32, px
    to the nearest edge pixel; ``score`` (H, W) float32, the point's log factor
    ``log(1 + exp(-d^2 / (2 sigma_e^2)) / (sqrt(2 pi) sigma_e q lambda))`` (Huang
    Sec. 5.2 with the nearest edge only), 0 beyond ``search_px``."""

    distance: np.ndarray
    score: np.ndarray

    def at(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The tables at image points ``uv`` (..., 2) px, rounded to the pixel: ``score``
        (0 outside the image) and ``distance`` (inf outside), each of shape (...)."""
        col = np.rint(uv[..., 0]).astype(np.int64, copy=False)
        row = np.rint(uv[..., 1]).astype(np.int64, copy=False)
        h, w = self.score.shape
        inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
        r, c = np.clip(row, 0, h - 1), np.clip(col, 0, w - 1)
        return (np.where(inside, self.score[r, c], 0.0),
                np.where(inside, self.distance[r, c], np.inf))


def edge_lookup(edges: np.ndarray, options: LikelihoodOptions = LikelihoodOptions()
                ) -> EdgeLookup:
    """The tables of :class:`EdgeLookup` for an edge map (H, W) (255 on edges)."""
    distance = cv2.distanceTransform((edges == 0).astype(np.uint8), cv2.DIST_L2,
                                     cv2.DIST_MASK_PRECISE)
    score = np.zeros(distance.shape, dtype=np.float32)
    near = distance <= options.search_px  # the rest of the frame scores 0: skip its exp
    d = distance[near].astype(np.float64)
    score[near] = np.log1p(options.inverse_clutter * np.exp(-d ** 2 / (2 * options.sigma_px ** 2)))
    return EdgeLookup(distance.astype(np.float32, copy=False), score)


@dataclass(frozen=True)
class FingerGeometry:
    """What the likelihood needs of a model, computed once.

    link_rows, lengths, radii : (L,) shape rows, axis lengths and half-widths (mm) of the
        finger patches (every ``link`` of the model that is not the palm).
    skip : (L, L) pairs not tested for occlusion (a patch, its parent and its child).
    palm_row : shape row of the palm box; palm_outline : (4, 3) its corners in that shape
        frame, mm (the face at the box centre's z: the cardboard palm plane).
    link_names : (L,) the patches' link names.
    """

    link_rows: np.ndarray
    lengths: np.ndarray
    radii: np.ndarray
    skip: np.ndarray
    palm_row: int
    palm_outline: np.ndarray
    link_names: tuple[str, ...]

    @classmethod
    def of(cls, model: KinematicModel) -> FingerGeometry:
        links = [link for link in model.links if link.kind == "link"]
        rows = np.array([link.row for link in links], dtype=int)
        shaped = {link.row for link in model.links}
        skip = np.eye(len(links), dtype=bool)
        for a, la in enumerate(links):
            for b, lb in enumerate(links):
                skip[a, b] |= _chain_neighbours(model, shaped, la.row, lb.row)
        palm = next(link for link in model.links if link.kind == "palm")
        sx, sy, _ = palm.size
        cx, cy, cz = palm.centre
        outline = np.array([[cx - sx / 2, cy - sy / 2, cz], [cx + sx / 2, cy - sy / 2, cz],
                            [cx + sx / 2, cy + sy / 2, cz], [cx - sx / 2, cy + sy / 2, cz]])
        return cls(rows, np.array([link.length for link in links]),
                   np.array([link.radius for link in links]), skip, palm.row, outline,
                   tuple(link.name for link in links))


def _chain_neighbours(model: KinematicModel, shaped: set[int], row_a: int, row_b: int
                      ) -> bool:
    """Whether the shape rows are consecutive bodies of one chain (rows without shapes,
    such as the thumb's fixed MP frame, in between)."""
    for start, end in ((row_a, row_b), (row_b, row_a)):
        r = model.parent[end]
        while r >= 0 and r != start and r not in shaped:
            r = model.parent[r]
        if r == start:
            return True
    return False


@dataclass(frozen=True)
class LikelihoodResult:
    """Per hypothesis: ``log_likelihood`` (N,), ``visible`` points, points ``with_edge``,
    ``rms_px`` RMS offset of the nearest edge over the points with one (NaN without);
    ``per_link`` (N, L) each patch's share of ``log_likelihood`` when asked for, else
    None."""

    log_likelihood: np.ndarray
    visible: np.ndarray
    with_edge: np.ndarray
    rms_px: np.ndarray
    per_link: np.ndarray | None = None


def finger_log_likelihood(model: KinematicModel, geometry: FingerGeometry, q: np.ndarray,
                          cameras: list[Camera] | tuple[Camera, ...],
                          edge_maps: list[np.ndarray] | tuple[np.ndarray, ...],
                          options: LikelihoodOptions = LikelihoodOptions(),
                          lookups: list[EdgeLookup] | tuple[EdgeLookup, ...] | None = None,
                          per_link: bool = False) -> LikelihoodResult:
    """``log p(Z | X)`` (Huang Sec. 5.2) of states ``q`` (N, n_q), summed over cameras.

    Batched forward kinematics for all N states, then one compiled pass per camera.
    ``lookups`` (one :class:`EdgeLookup` per camera) are the ``"distance"`` search's
    tables; computed from ``edge_maps`` when not given (pass them to reuse them within a
    frame). The ``"normal"`` search uses them when given, to skip the search from a point
    farther from every edge than the search reaches (the same result, sooner).
    """
    use_lookup = options.search == "distance"
    if use_lookup and lookups is None:
        lookups = [edge_lookup(e, options) for e in edge_maps]
    skip_far = lookups is not None and not use_lookup
    if lookups is None:
        lookups = [EdgeLookup(np.zeros((1, 1), np.float32), np.zeros((1, 1), np.float32))
                   ] * len(edge_maps)
    shapes = forward_kinematics(model, np.atleast_2d(q)).T_world_shape
    ts = (np.arange(options.points_per_link) + 0.5) / options.points_per_link
    n = len(shapes)
    log_l = np.zeros(n)
    stats = np.zeros((n, 3))
    links = np.zeros((n if per_link else 0, len(geometry.link_rows)))  # summed over cameras
    for camera, edges, lookup in zip(cameras, edge_maps, lookups, strict=True):
        out_l = np.empty(n)
        out_s = np.empty((n, 3))
        edge_likelihood_kernel(shapes, geometry.link_rows, geometry.lengths, geometry.radii, ts,
                               geometry.skip, geometry.palm_row, geometry.palm_outline,
                               camera.projection_params, edges, int(options.search_px),
                               float(options.sigma_px), float(options.inverse_clutter),
                               float(options.occlusion_margin_mm), lookup.score,
                               lookup.distance, use_lookup, skip_far, out_l, out_s, links)
        log_l += out_l
        stats += out_s
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt(stats[:, 2] / stats[:, 1])
    return LikelihoodResult(log_l, stats[:, 0], stats[:, 1], rms,
                            links if per_link else None)


def fit_finger_width(model: KinematicModel, geometry: FingerGeometry, q: np.ndarray,
                     cameras, edge_maps: list[np.ndarray],
                     scales: np.ndarray = np.arange(0.7, 1.31, 0.05),  # noqa: B008
                     options: LikelihoodOptions = LikelihoodOptions(),
                     lookups: list[EdgeLookup] | None = None,
                     min_change: float = 0.1) -> float:
    """The scale of every finger patch's half-width (one for the hand) under which the
    frame's likelihood at the known state ``q`` (n_q,) is highest: the patch-size
    calibration of Huang Sec. 4.2 for the fingers (a user's fingers are thinner or
    thicker than the model's; the flesh hand's taper). Returns the scale: 1 when nothing
    beats the model's widths or the best differs from 1 by less than ``min_change`` (one
    step of ``scales`` is within what the likelihood can tell on one frame)."""
    Q = np.asarray(q, dtype=float)[None]
    scores = [finger_log_likelihood(model, replace(geometry, radii=geometry.radii * s), Q,
                                    cameras, edge_maps, options, lookups).log_likelihood[0]
              for s in scales]
    k = int(np.argmax(scores))
    at_one = finger_log_likelihood(model, geometry, Q, cameras, edge_maps, options,
                                   lookups).log_likelihood[0]
    best = float(scales[k])
    return best if scores[k] > at_one and abs(best - 1.0) >= min_change - 1e-9 else 1.0
