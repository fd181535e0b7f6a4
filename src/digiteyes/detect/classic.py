"""A hand detector with no learned parts, for plain backgrounds.

Steps (each a function below):

1. segmentation (:mod:`~digiteyes.detect.segmentation`): skin and not background;
2. the largest blob; its palm centre and radius from the distance transform (the centre of
   the largest inscribed circle; where the image border cuts the forearm, the largest
   such circle away from the cut);
3. digit tips as the peaks of the contour's distance from the palm centre (at least
   ``TIP_DISTANCE`` palm radii out) that end a thin limb: a peak whose limb is thicker
   than ``THICK`` palm radii is the end of the wrist or forearm (a sleeve or the end of
   the picture cuts it); the wrist lies towards the thickest such end, else where the
   blob crosses a circle of ``RING`` palm radii in a crossing wider than ``WIDE`` radii
   that fewer than two tips lie beyond (else opposite to the tips), and a peak towards
   the wrist is not a tip;
4. a model-based labelling: the model's keypoints of an open hand (a right hand,
   seen from its palmar or its dorsal side) are placed on the image by the similarity that
   puts the model's palm centre on the blob's, its wrist towards the image wrist and its
   palm radius on the blob's; the side whose digit directions match the found tips best
   (optimal assignment) names the digits; each digit's joints lie on the line from its
   base to its tip at the model's link-length fractions. Where no similarity fits the
   tips (a hand tilted away foreshortens its digits), a found digit's joints follow its
   limb's medial axis instead. Digits not found (curled) get a guess near their base
   with low confidence.

The 21 keypoints then go to :func:`~digiteyes.detect.model_fit.fit_keypoints`.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.sparse.csgraph import connected_components

from digiteyes.camera import Camera
from digiteyes.detect.candidate import HandCandidate, bbox_of
from digiteyes.detect.hand21 import DIGITS
from digiteyes.detect.model_fit import palm_points
from digiteyes.detect.segmentation import BackgroundModel, hand_mask, largest_blob
from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import KinematicModel, clip_to_limits, load_model
from digiteyes.kinematics.rotations import wrap_angle

RING = 1.75
"""Radius of the crossing circle, in palm radii (through the proximal phalanges)."""
WIDE = 1.1
"""A crossing wider than this many palm radii is the wrist or forearm, not a digit."""
TIP_DISTANCE = 1.5
"""A digit tip lies at least this many palm radii from the palm centre."""
THICK = 0.5
"""A limb whose largest inscribed circle within ``THICK_DEPTH`` palm radii of its end has
a radius above this many palm radii is a wrist or forearm, not a digit (digits: under
0.4; a forearm cut by a sleeve: 0.55 and more)."""
THICK_DEPTH = 0.8
"""How far in from a peak (palm radii) its limb's thickness is measured."""
VALLEY = 0.25
"""Between two digit tips the contour comes at least this many palm radii closer to the
palm centre than the nearer tip (the web between the digits)."""
PALM_RADIUS_MM = 30.0
"""Radius of the largest circle inscribed in the palm silhouette, mm, for the nominal hand
(about half its palm width of 56 mm); only the first placement uses it."""
OPEN_HAND_DEG = {"index.abd": -20.0, "middle.abd": -5.0, "ring.abd": 8.0, "little.abd": 22.0,
                 "thumb.cmc_abd": 20.0, "thumb.cmc_flex": 35.0}
"""Joint angles (degrees) of the open hand of the template: fingers spread, the thumb
swung away from the index in the palm plane (other joints at zero)."""


SHORT_LIMB = 0.3
"""Where no similarity fits, the digits follow their silhouettes only if each found digit's
silhouette gives it at least this fraction of the template's length (at the first
placement): a shorter one is a curled digit, which the assignment can name for another,
and the hand is not the open hand tilted away that the silhouettes explain."""
BORDER = 4
"""Contour points this close to the image border (px, working size) are where the frame
cuts the arm (segmentation's smoothing keeps the mask a pixel or two off the border)."""
ARM_CUT = 1.0
"""A border run of the contour at least this many times the blob's largest inscribed
radius wide is a forearm cut by the frame (a digit, or two touching, is narrower)."""
PALM_PEAK = 0.6
"""Where the image border cuts the blob, the palm is the inscribed circle farthest from
the cut among those at least this fraction of the largest."""
AXIS_STEP = 0.12
"""Step of the march along a digit's medial axis, palm radii."""
AXIS_LENGTH = 4.0
"""The march stops after this many palm radii (longer than any digit)."""
AXIS_REACH = 1.2
"""A cross-section reaching this many palm radii to one side is the palm, not a digit."""
AXIS_SETTLE = 3
"""Steps near the tip (its rounded end) that never stop the march."""
WIDENS = 1.7
"""The palm begins where a digit's cross-section exceeds this many times its median
width so far."""
HIDDEN = {"thumb": 1.0, "index": 0.7, "middle": 0.7, "ring": 0.7, "little": 0.7}
"""The part of each digit's first link that the palm's silhouette hides: the thumb's
whole metacarpal (its limb meets the palm at the MCP), and of a finger's proximal phalanx
the part under the palm up to the web between the fingers (the MCP joint sits under the
distal palmar crease): about 0.7 of it, measured 0.6-0.8 against MediaPipe's joints on
the real recording."""


@dataclass(frozen=True)
class BlobAnalysis:
    """What the blob gives before labelling (pixels of the analysed image).

    Attributes
    ----------
    mask : bool (H, W) the hand blob.
    centre : (2,) palm centre; radius : palm radius, px.
    tips : (T, 2) digit tips found; tip_angles : (T,) their directions from the centre, rad.
    wrist_angle : direction of the wrist from the centre, rad (image axes, v down).
    wrist_found : whether a wide crossing gave the wrist (else: opposite to the digits).
    """

    mask: np.ndarray
    centre: np.ndarray
    radius: float
    tips: np.ndarray
    tip_angles: np.ndarray
    wrist_angle: float
    wrist_found: bool


def analyse_blob(mask: np.ndarray) -> BlobAnalysis | None:
    """Palm, digit tips and wrist direction of a hand blob (bool (H, W)); None when the
    blob is too small to be a hand (palm radius under 4 px)."""
    blob = mask.astype(np.uint8)
    dist = cv2.distanceTransform(blob, cv2.DIST_L2, 5)
    if dist.max() < 4.0:
        return None
    contours, _ = cv2.findContours(blob, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    contour = max(contours, key=len).reshape(-1, 2).astype(float)
    cut = _arm_cut(contour, blob.shape, float(dist.max()))
    arm_end = contour[cut].mean(axis=0) if cut.any() else None
    centre = _palm_centre(dist, arm_end)
    radius = float(dist[int(centre[1]), int(centre[0])])
    ring = RING * radius
    angles = np.linspace(-np.pi, np.pi, 720, endpoint=False)
    pu = np.round(centre[0] + ring * np.cos(angles)).astype(int)
    pv = np.round(centre[1] + ring * np.sin(angles)).astype(int)
    inside = (pu >= 0) & (pu < blob.shape[1]) & (pv >= 0) & (pv < blob.shape[0])
    on = np.zeros(len(angles), dtype=bool)
    on[inside] = blob[pv[inside], pu[inside]] > 0
    runs = _circular_runs(on)
    offsets = contour - centre
    c_dist = np.hypot(offsets[:, 0], offsets[:, 1])
    c_angle = np.arctan2(offsets[:, 1], offsets[:, 0])
    step = angles[1] - angles[0]
    # where the frame cuts the arm the contour runs on away from the palm: a cut point
    # counts as the farthest, so that the slopes up to the cut make no peaks
    far = np.where(cut, c_dist.max() + 1.0, c_dist)
    peaks = [i for i in _contour_peaks(far, TIP_DISTANCE * radius, VALLEY * radius,
                                       0.5 * radius, keep=10) if not cut[i]][:8]
    thickness = [_limb_thickness(dist, contour[i], centre, THICK_DEPTH * radius)
                 for i in peaks]
    ends = [(t, i) for t, i in zip(thickness, peaks, strict=True) if t > THICK * radius]
    tips = [i for t, i in zip(thickness, peaks, strict=True) if t <= THICK * radius]
    # a wide crossing that two or more tips lie beyond is digits held together, unless
    # it leads to where the frame cuts the arm
    arm = None if arm_end is None else np.arctan2(*(arm_end - centre)[::-1])
    wide = []
    for start, length in runs:
        middle, half = angles[0] + (start + 0.5 * (length - 1)) * step, 0.5 * length * step
        beyond = sum(abs(wrap_angle(c_angle[i] - middle)) < half for i in tips)
        if ring * length * step > WIDE * radius and (
                beyond < 2 or (arm is not None and abs(wrap_angle(arm - middle)) < half)):
            wide.append((ring * length * step, middle))
    if arm is not None:
        # the frame cuts the forearm: a thick end or a wide crossing facing away from the
        # cut is a fist's curled fingers or fingers held together, not the wrist
        ends = [(t, i) for t, i in ends if abs(wrap_angle(c_angle[i] - arm)) < np.pi / 2]
        wide = [(w, m) for w, m in wide if abs(wrap_angle(m - arm)) < np.pi / 2]
    wrist = c_angle[max(ends)[1]] if ends else max(wide)[1] if wide else arm
    if wrist is not None:
        tips = [i for i in tips if abs(wrap_angle(c_angle[i] - wrist)) > np.radians(50.0)]
    tips = tips[:5]
    tip_angles = [c_angle[i] for i in tips]
    tips = [contour[i] for i in tips]
    if wrist is not None:
        wrist_angle, wrist_found = float(wrist), True
    elif tips:
        mean = np.mean([[np.cos(a), np.sin(a)] for a in tip_angles], axis=0)
        wrist_angle, wrist_found = float(np.arctan2(-mean[1], -mean[0])), False
    else:
        wrist_angle, wrist_found = np.pi / 2, False
    return BlobAnalysis(mask, centre, radius, np.array(tips).reshape(-1, 2),
                        np.array(tip_angles), float(wrist_angle), wrist_found)


def _arm_cut(contour: np.ndarray, shape: tuple[int, int], thickest: float) -> np.ndarray:
    """Which contour points (C, 2) px lie where the image border cuts the forearm:
    runs of contour points within :data:`BORDER` px of the border (runs less than half of
    ``thickest`` apart joined) that span at least :data:`ARM_CUT` times the blob's
    largest inscribed radius ``thickest`` (a finger that leaves the picture makes a
    narrower run, and keeps its tip there). Bool (C,)."""
    height, width = shape
    near = ((contour[:, 0] < BORDER) | (contour[:, 0] >= width - BORDER)
            | (contour[:, 1] < BORDER) | (contour[:, 1] >= height - BORDER))
    cut = np.zeros(len(contour), dtype=bool)
    if not near.any():
        return cut
    runs = [(start + np.arange(length)) % len(contour)
            for start, length in _circular_runs(near)]
    # runs a short way apart are one cut (a notch in the mask where the arm leaves)
    close = np.array([[np.linalg.norm(contour[a][:, None] - contour[b][None], axis=2).min()
                       < 0.5 * thickest for b in runs] for a in runs])
    _, group = connected_components(close, directed=False)
    for k in range(group.max() + 1):
        members = np.concatenate([run for run, g in zip(runs, group, strict=True) if g == k])
        span = contour[members].max(axis=0) - contour[members].min(axis=0)
        if np.hypot(*span) >= ARM_CUT * thickest:
            cut[members] = True
    return cut


def _palm_centre(dist: np.ndarray, arm_end: np.ndarray | None) -> np.ndarray:
    """The palm centre (2,) px: the centre of the largest circle inscribed in the blob
    (``dist`` its distance transform), or, where the image border cuts the blob
    (``arm_end`` (2,) px, the mean of the cut's contour points: an arm entering the
    picture), of the inscribed circle farthest from the cut among those at least
    :data:`PALM_PEAK` times the largest: a forearm seen whole is often thicker than a
    fist or a palm seen edge-on."""
    v, u = np.unravel_index(int(np.argmax(dist)), dist.shape)
    if arm_end is None:
        return np.array([u, v], dtype=float)
    size = 2 * max(1, int(0.5 * dist.max())) + 1
    peak = (dist >= cv2.dilate(dist, np.ones((size, size), np.uint8))) & (
        dist >= PALM_PEAK * dist.max())
    vs, us = np.nonzero(peak)
    far = np.linalg.norm(np.column_stack([us, vs]) - arm_end, axis=1)
    best = int(np.argmax(far))
    return np.array([us[best], vs[best]], dtype=float)


def _limb_thickness(dist: np.ndarray, end: np.ndarray, centre: np.ndarray,
                    depth: float) -> float:
    """Radius (px) of the largest inscribed circle (distance transform ``dist``) on the
    segment from a limb's ``end`` (contour point) ``depth`` px towards the palm ``centre``."""
    toward = centre - end
    toward /= max(float(np.linalg.norm(toward)), 1e-9)
    steps = np.linspace(0.0, depth, max(2, int(depth)))
    points = np.round(end + steps[:, None] * toward).astype(int)
    points[:, 0] = np.clip(points[:, 0], 0, dist.shape[1] - 1)
    points[:, 1] = np.clip(points[:, 1], 0, dist.shape[0] - 1)
    return float(dist[points[:, 1], points[:, 0]].max())


def _contour_peaks(distance: np.ndarray, min_distance: float, valley: float,
                   window: int, keep: int = 5) -> list[int]:
    """Contour indices of at most ``keep`` digit tips, farthest first: local maxima of the
    distance from the palm centre (within ``window`` contour points either side) farther than
    ``min_distance``; a peak counts only if the contour dips by at least ``valley`` (px)
    below it on the way to every farther peak (the web between two digits), otherwise it
    is a bump on the same digit."""
    window = max(3, int(window))
    padded = np.concatenate([distance[-window:], distance, distance[:window]])
    local_max = np.lib.stride_tricks.sliding_window_view(padded, 2 * window + 1).max(axis=1)
    candidates = np.flatnonzero((distance >= local_max) & (distance > min_distance))
    kept: list[int] = []
    for i in candidates[np.argsort(-distance[candidates])]:
        separate = True
        for j in kept:
            lo, hi = sorted((int(i), j))
            inner = distance[lo:hi + 1].min()
            outer = min(distance[hi:].min(initial=np.inf), distance[:lo + 1].min())
            if max(inner, outer) > distance[i] - valley:
                separate = False
                break
        if separate:
            kept.append(int(i))
    return kept[:keep]


def _circular_runs(on: np.ndarray) -> list[tuple[int, int]]:
    """(start, length) of the runs of True in a circular bool array."""
    n = len(on)
    if on.all():
        return [(0, n)]
    shift = int(np.argmin(on))  # start the scan at a False sample
    rolled = np.roll(on, -shift)
    runs, start = [], None
    for i, value in enumerate(np.append(rolled, False)):
        if value and start is None:
            start = i
        elif not value and start is not None:
            runs.append(((start + shift) % n, i - start))
            start = None
    return runs


class HandTemplate:
    """The model's 21 keypoints of an open hand (:data:`OPEN_HAND_DEG`) projected on the
    palm plane (mm).

    Attributes
    ----------
    xy : (21, 2) palm-frame x, y (fingers along +y, thumb and index on +x), mm.
    centre : (2,) the palm slab's centre, mm.
    fractions : per digit, (3,) where its second, third and fourth keypoint lie along the
        line from its first to its tip (cumulative link lengths).
    """

    def __init__(self, model: KinematicModel) -> None:
        q = model.neutral()
        for name, value in OPEN_HAND_DEG.items():
            q[model.state_index(name)] = np.radians(value)
        points = palm_points(model, clip_to_limits(model, q))
        palm = next(link for link in model.links if link.kind == "palm")
        self.centre = np.asarray(palm.centre[:2], dtype=float)
        self.xy = points[:, :2]
        self.fractions = {}
        for i, digit in enumerate(DIGITS):
            keys = [1 + 4 * i + j for j in range(4)]
            segment = np.linalg.norm(np.diff(points[keys], axis=0), axis=1)
            self.fractions[digit] = np.cumsum(segment) / segment.sum()

    def place(self, centre: np.ndarray, wrist_angle: float, scale: float,
              dorsal: bool) -> np.ndarray:
        """The 21 template points in the image (21, 2) px: palm centre on ``centre``, the
        wrist towards ``wrist_angle``, ``scale`` px per mm; ``dorsal`` mirrors x (the back
        of a right hand)."""
        local = self.xy - self.centre
        local = np.column_stack([-local[:, 0] if dorsal else local[:, 0], -local[:, 1]])
        # template image axes: the wrist lies along +v (fingers up); turn +v onto the wrist
        turn = wrist_angle - np.pi / 2
        c, s = np.cos(turn), np.sin(turn)
        return centre + scale * local @ np.array([[c, s], [-s, c]])


def similarity_2d(source: np.ndarray, target: np.ndarray,
                  weights: np.ndarray) -> tuple[complex, complex]:
    """Weighted least-squares 2D similarity ``y = a x + b`` (complex ``a``: scale and
    rotation, no reflection) between point sets (P, 2)."""
    x = source[:, 0] + 1j * source[:, 1]
    y = target[:, 0] + 1j * target[:, 1]
    w = weights / weights.sum()
    mx, my = (w * x).sum(), (w * y).sum()
    a = (w * np.conj(x - mx) * (y - my)).sum() / (w * np.abs(x - mx) ** 2).sum()
    return complex(a), complex(my - a * mx)


def _apply(a: complex, b: complex, points: np.ndarray) -> np.ndarray:
    z = a * (points[:, 0] + 1j * points[:, 1]) + b
    return np.column_stack([z.real, z.imag])


def _match(blob: BlobAnalysis, placed: np.ndarray) -> tuple[dict[int, int], float]:
    """Optimal assignment of the found tips to the digits of a placed template by their
    directions from the palm centre; returns {digit: tip} and the mean angle error (rad)."""
    tips = placed[[4, 8, 12, 16, 20]]
    digit_angles = np.arctan2(tips[:, 1] - blob.centre[1], tips[:, 0] - blob.centre[0])
    if not len(blob.tips):
        return {}, float(np.pi)
    cost = np.abs(wrap_angle(blob.tip_angles[:, None] - digit_angles[None, :]))
    found, digit = linear_sum_assignment(cost)
    return dict(zip(digit.tolist(), found.tolist(), strict=True)), float(cost[found, digit].mean())


def _plausible(a: complex, a0: complex) -> bool:
    """A similarity ``a`` within a factor 1.6 in scale and 50 degrees in rotation of the
    placement ``a0`` from the palm radius and the wrist (a wrong assignment can turn the
    template over)."""
    ratio = a / a0
    return 1 / 1.6 < abs(ratio) < 1.6 and abs(np.angle(ratio)) < np.radians(50.0)


def label_keypoints(blob: BlobAnalysis, template: HandTemplate,
                    palm_radius_mm: float = PALM_RADIUS_MM, rounds: int = 3,
                    sides: tuple[bool, ...] = (False, True)
                    ) -> tuple[np.ndarray, np.ndarray, bool, float]:
    """21 keypoints (px), their confidences, whether the dorsal side faces the camera and
    the assignment cost (mean angle error, rad) from a blob analysis (module step 4).

    For each side: place the template by the palm radius and the wrist direction turned by
    up to 60 degrees (the turn whose assignment fits best), assign the tips, then
    alternate a weighted similarity fit (palm centre and matched tips onto the template's
    palm centre and tips) with a new assignment, ``rounds`` times. The found digits'
    joints lie on the line from the template's base to the tip; where no similarity
    within :func:`_plausible` of the first placement fits the tips (a hand tilted out of
    the image plane foreshortens its digits, which no similarity of the open template
    explains), they come from the digits' silhouettes instead (:func:`_digit_from_limb`),
    unless one of them is shorter than :data:`SHORT_LIMB` of the template's.
    """
    best = None
    for dorsal in sides:
        # the digits need not point away from the forearm (a bent wrist): try turns
        scale = blob.radius / palm_radius_mm
        tries = []
        for offset in np.radians(np.arange(-60.0, 61.0, 5.0)):
            placed = template.place(blob.centre, blob.wrist_angle + offset, scale, dorsal)
            tries.append((*_match(blob, placed)[::-1], offset, placed))
        # equal fits (no tip found: every turn scores pi) keep the measured wrist
        total, match, offset, placed = min(tries, key=lambda t: (t[0], abs(t[2])))
        local = template.place(np.zeros(2), np.pi / 2, 1.0, dorsal)  # template, mm
        turn = blob.wrist_angle + offset - np.pi / 2
        a0 = scale * complex(np.cos(turn), np.sin(turn))
        fitted = False
        for _ in range(rounds):
            if len(match) < 2:
                break
            digits = sorted(match)
            source = np.vstack([np.zeros((1, 2)),
                                local[[4 * d + 4 for d in digits]]])
            target = np.vstack([blob.centre, blob.tips[[match[d] for d in digits]]])
            weights = np.r_[1.0, np.ones(len(digits))]
            a, b = similarity_2d(source, target, weights)
            if not _plausible(a, a0):
                break
            placed = _apply(a, b, local)
            fitted = True
            match, total = _match(blob, placed)
        if best is None or total < best[0]:
            best = (total, dorsal, placed, match, fitted)
    total, dorsal, placed, match, fitted = best
    keypoints = placed.copy()
    confidence = np.full(21, 0.6)
    limbs = {} if fitted else {i: _digit_from_limb(blob, blob.tips[match[i]], DIGITS[i],
                                                  template) for i in match}
    if any(np.linalg.norm(limb[3] - limb[0])
           < SHORT_LIMB * np.linalg.norm(placed[4 * i + 4] - placed[4 * i + 1])
           for i, limb in limbs.items()):
        limbs = {}  # a curled digit: not an open hand tilted away
    for i, digit in enumerate(DIGITS):
        keys = [1 + 4 * i + j for j in range(4)]
        base = placed[keys[0]]
        if i in limbs:  # the template does not fit: follow the limb
            keypoints[keys] = limbs[i]
            confidence[keys] = (0.3, 0.5, 0.5, 0.9)  # the base is past the limb's end
            continue
        if i in match:
            tip = blob.tips[match[i]]
            confidence[keys[1:]] = (0.5, 0.5, 0.9)
        else:  # curled: the tip folds back towards the palm centre
            tip = base + 0.35 * (blob.centre - base)
            confidence[keys[1:]] = 0.1
        keypoints[keys[1:]] = base + template.fractions[digit][:, None] * (tip - base)
    return keypoints, confidence, dorsal, total


def _digit_from_limb(blob: BlobAnalysis, tip: np.ndarray, digit: str,
                     template: HandTemplate) -> np.ndarray:
    """A found digit's four keypoints (4, 2) px, base to tip, from its silhouette alone.

    The limb's medial axis is followed from the tip to where the limb meets the palm
    (:func:`limb_axis`) and extended straight on by the part of the digit's first link
    the palm hides (:data:`HIDDEN`); the joints sit at the template's link-length
    fractions of that path.
    """
    axis = limb_axis(blob.mask, tip, blob.centre, blob.radius)
    seen = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(axis, axis=0), axis=1))]
    if seen[-1] < 1e-6:
        return np.repeat(tip[None], 4, axis=0)
    back = axis[-1] - axis[max(0, len(axis) - 4)]
    back = back / max(float(np.linalg.norm(back)), 1e-9)
    fractions = template.fractions[digit]
    length = seen[-1] / (1.0 - HIDDEN[digit] * fractions[0])
    along = length * (1.0 - np.r_[0.0, fractions])  # from the tip
    out = np.empty((4, 2))
    for k, s in enumerate(along):
        if s <= seen[-1]:
            out[k] = [np.interp(s, seen, axis[:, 0]), np.interp(s, seen, axis[:, 1])]
        else:
            out[k] = axis[-1] + (s - seen[-1]) * back
    return out


def limb_axis(mask: np.ndarray, tip: np.ndarray, centre: np.ndarray, radius: float
              ) -> np.ndarray:
    """Medial axis (K, 2) px of the limb that ends at ``tip``, from the tip to where it
    meets the palm.

    March from the tip towards the palm ``centre`` in steps of :data:`AXIS_STEP` palm
    radii; at each step the mask's cross-section perpendicular to the current direction
    gives the limb's width and middle (the next axis point), and the direction follows
    the last few axis points (a bent digit). The march stops where the cross-section
    widens to :data:`WIDENS` times the limb's median width so far, or runs past
    ``AXIS_REACH`` palm radii to one side, or leaves the mask: the palm begins there.
    """
    height, width = mask.shape
    direction = centre - tip
    direction = direction / max(float(np.linalg.norm(direction)), 1e-9)
    point = np.asarray(tip, dtype=float)
    reach = AXIS_REACH * radius
    offsets = np.arange(0.0, reach, 0.5)
    points, widths = [point], []
    for k in range(int(AXIS_LENGTH / AXIS_STEP)):
        ahead = point + AXIS_STEP * radius * direction
        u, v = np.round(ahead).astype(int)
        if not (0 <= u < width and 0 <= v < height and mask[v, u]):
            break
        normal = np.array([-direction[1], direction[0]])
        extent = []
        for sign in (1.0, -1.0):
            line = np.round(ahead + sign * offsets[:, None] * normal).astype(int)
            ok = ((line[:, 0] >= 0) & (line[:, 0] < width) & (line[:, 1] >= 0)
                  & (line[:, 1] < height))
            inside = np.zeros(len(offsets), dtype=bool)
            inside[ok] = mask[line[ok, 1], line[ok, 0]]
            out = np.flatnonzero(~inside)
            extent.append(offsets[out[0]] if len(out) else reach)
        across = extent[0] + extent[1]
        if k >= AXIS_SETTLE and (across > WIDENS * float(np.median(widths))
                                 or max(extent) >= reach):
            break
        widths.append(across)
        point = ahead + 0.5 * (extent[0] - extent[1]) * normal
        points.append(point)
        turn = points[-1] - points[max(0, len(points) - 4)]
        if np.linalg.norm(turn) > 0:
            direction = turn / np.linalg.norm(turn)
    return np.array(points)


SIDE_MARGIN = 0.02
"""With ``remember_side``: a silhouette whose palm-side and back-side labellings fit the
tips' directions within this much of each other (mean angle error, rad) is ambiguous."""


class ClassicDetector:
    """Skin/background segmentation, blob geometry and a model template (no learning).

    Parameters
    ----------
    model : the hand model whose neutral keypoints label the digits (default ``hand``).
    background : a :class:`BackgroundModel` of a static camera, or None for the border
        colour (a plain wall).
    max_side : images are analysed at most this many pixels on their longer side.
    min_area_fraction : blobs smaller than this fraction of the image are not hands.
    remember_side : the images are frames of footage, in order. A silhouette cannot tell a
        right palm from a right back, and with the thumb curled four fanned fingers fit
        both labellings about as well (a mirrored one names the little finger the index);
        where the two sides fit within :data:`SIDE_MARGIN`, the side of the camera's last
        clear labelling is kept (a hand keeps its side between frames). On the real video
        (palm on throughout) the worst digit's median gap to MediaPipe's keypoints
        0.55 -> 0.47 palm lengths (docs/initialisation.md).
    """

    name = "classic"
    locates_joints = False  # keypoints placed by a hand template on the silhouette

    def __init__(self, model: KinematicModel | None = None,
                 background: BackgroundModel | None = None, max_side: int = 400,
                 min_area_fraction: float = 0.002, remember_side: bool = False) -> None:
        self.template = HandTemplate(load_model("hand") if model is None else model)
        self.background = background
        self.max_side = int(max_side)
        self.min_area_fraction = float(min_area_fraction)
        self.remember_side = bool(remember_side)
        self._dorsal: dict[str | None, bool] = {}  # camera name -> side of the last clear one

    def analyse(self, image: np.ndarray) -> tuple[BlobAnalysis | None, float]:
        """The blob analysis at the working size and the factor back to image pixels."""
        image = np.asarray(image)
        if image.dtype != np.uint8 or image.ndim not in (2, 3):
            raise DigitEyesError(f"classic detector: expected a uint8 grey or RGB image, got "
                                 f"{image.dtype} {image.shape}")
        height, width = image.shape[:2]
        factor = min(1.0, self.max_side / max(height, width))
        small = image if factor == 1.0 else cv2.resize(
            image, (round(width * factor), round(height * factor)),
            interpolation=cv2.INTER_AREA)
        background = self.background
        if background is not None and factor != 1.0:
            raise DigitEyesError("classic detector: a background model needs images of at most "
                                 f"{self.max_side} px (build it at the working size)")
        blob = largest_blob(hand_mask(small, background))
        if blob is None or blob.sum() < self.min_area_fraction * blob.size:
            return None, 1.0 / factor
        return analyse_blob(blob), 1.0 / factor

    def detect(self, image: np.ndarray, camera: Camera | None = None) -> list[HandCandidate]:
        """At most one hand: the largest skin (or foreground) blob, labelled by the model
        (as a right hand; handedness None: a silhouette cannot tell a right palm from a
        left back)."""
        blob, back = self.analyse(image)
        if blob is None:
            return []
        keypoints, confidence, _, angle_cost = self._label(blob, camera)
        keypoints = (keypoints + 0.5) * back - 0.5
        n_tips = len(blob.tips)
        score = float(np.clip(n_tips / 5.0, 0.0, 1.0) * np.exp(-angle_cost / 0.5))
        full = cv2.resize(blob.mask.astype(np.uint8), (np.shape(image)[1], np.shape(image)[0]),
                          interpolation=cv2.INTER_NEAREST) > 0 if back != 1.0 else blob.mask
        vs, us = np.nonzero(blob.mask)
        box = bbox_of((np.column_stack([us, vs]) + 0.5) * back - 0.5)
        return [HandCandidate(keypoints, confidence, score, box, None, self.name,
                              mask=full)]

    def _label(self, blob: BlobAnalysis, camera: Camera | None
               ) -> tuple[np.ndarray, np.ndarray, bool, float]:
        """:func:`label_keypoints`, keeping the camera's side where the silhouette is
        ambiguous (``remember_side``)."""
        if not self.remember_side:
            return label_keypoints(blob, self.template)
        palmar, dorsal = (label_keypoints(blob, self.template, sides=(side,))
                          for side in (False, True))
        key = None if camera is None else camera.name
        if abs(palmar[3] - dorsal[3]) >= SIDE_MARGIN or key not in self._dorsal:
            self._dorsal[key] = dorsal[3] < palmar[3]
        return dorsal if self._dorsal[key] else palmar
