"""The silhouette loss rule, shared by every tracker: does the model drawn at the estimate
explain the hand's silhouette as well as it did at the true first state?

One :class:`SilhouetteLoss` per track. On the first frame it fits each camera's
foreground threshold at the reference state the track starts from
(:func:`~digiteyes.features.foreground.fit_foreground`; a camera over a textured backdrop
gets none and is not checked) and keeps the silhouette check of the model drawn at that
state as the baseline (not the first estimate's: a tracker whose first estimate is already
wrong would take its error as the norm). Every frame (:meth:`SilhouetteLoss.check`) the
estimate is drawn in each checked camera and compared with the foreground
(:func:`~digiteyes.features.foreground.silhouette_check`); the frame is lost when

* the hand pixels beyond ``tolerance_px`` of the model, per model pixel, exceed their
  value at the start state by more than ``max_unexplained`` in any camera (a finger the pose has
  put elsewhere, or curled into the palm while the real one is out; in a colour camera
  where that value exceeded :data:`MAX_START_UNEXPLAINED`, an arm in view, only the
  pixels on the hand's side of a line across the model's wrist count), or
* a finger's fraction of model pixels beyond ``tolerance_px`` of the foreground exceeds
  its value at the start state by more than ``max_finger_outside`` (a finger drawn over the
  backdrop); that finger is flagged in the per-finger flags, or
* a digit whose end the estimate hides in every checked camera (though it showed at the
  start state) would, if it were open, cover pixels beyond the estimate of which more than
  ``max_hidden_unexplained`` are unexplained foreground in some camera
  (:func:`~digiteyes.features.foreground.unexplained_where_open`): the estimate has curled
  a finger out of sight while the real one is out. A thin finger's unexplained pixels are
  mostly eaten by the tolerance band, so the first rule misses it; this one looks only
  where that finger would be. That digit is flagged. With ``judge_curled_digits`` the
  same test is applied to every digit that showed at the start state, hidden or not: a
  finger the estimate holds curled in view while the real one has opened again (the desk
  camera's curling fingers, docs/templates.md).

Over a textured backdrop, where no grey threshold fits, a colour image is split by a
colour model of hand and backdrop learned on the first frame
(:mod:`~digiteyes.features.colour_foreground`), when that model splits its own frame.
Where neither does, the grey threshold is tried once more on the frame blurred against
sensor noise (:func:`~digiteyes.features.foreground.fit_foreground`): a noisy camera
over a plain backdrop (8 grey levels of noise) used to leave the rule off, and with it
every tracker's loss flag but the feature tracker's own rules.

With ``flag_hidden_fingers`` (off by default) a digit whose end (distal link and tip) the
estimate hides in every checked camera, though it showed at the start state, is flagged
too: no silhouette says where a hidden finger lies (:meth:`SilhouetteLoss.end_shown`).

Measured against the first frame, so that systematic differences of hand and model (a
fleshier palm, tapered fingers, a 10 % size difference) do not count. The thresholds were
chosen with the feature tracker on the flesh appearance, desk setup, two cameras, exact
hand (docs/accuracy.md) and are the same for every tracker.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from digiteyes.camera import Rig
from digiteyes.camera.working_size import resize_images, resized_camera, working_size
from digiteyes.errors import DigitEyesError
from digiteyes.features.colour_foreground import (
    ColourForeground,
    fit_colour_foreground,
    is_colour,
)
from digiteyes.features.foreground import (
    MARGIN_PX,
    Foreground,
    SilhouetteCheck,
    digit_links,
    fit_foreground,
    model_labels,
    silhouette_check,
    unexplained_where_open,
)
from digiteyes.features.slices import prepare_image
from digiteyes.kinematics import KinematicModel, Kinematics, forward_kinematics
from digiteyes.kinematics.anatomy import DIGITS, open_digits

CHECK_MAX_SIDE = 640
"""Longer side (px) of the images the rule works on: larger images (1280x720 footage) are
checked at this size, with the cameras for the resized images. The rule's pixel
tolerance was chosen on 640x480 renders, and a full-size check of 1280x720 footage cost
4.2 ms a frame (rasterising the model, mostly), a fifth of the keypoint tracker's
frame."""
TOLERANCE_PX = 5
"""Default distance (px) within which the two silhouettes may differ."""
MAX_UNEXPLAINED = 0.08
"""Default excess of unexplained hand pixels per model pixel over the first frame."""
MAX_START_UNEXPLAINED = 0.4
"""A camera split by the colour model whose foreground the model left unexplained by more
than this share of its own area at the start state is not judged by the
unexplained-pixels test (the other tests stand): what the model never explains there (an
arm in view, a sleeve of skin colour) moves on its own by more than a finger's share
(:data:`MAX_UNEXPLAINED`). The flesh renders start at 0.12-0.29 (its wrist and fleshier
palm); the real video, with the forearm in view, at 0.59 (docs/accuracy.md, "Over a
textured backdrop"). Grey-threshold cameras keep the test: there a large start share
came from automatic starts that were themselves wrong, and the test's firing as the
track got worse brought the re-detections that saved it (``bench auto-start``)."""
WRIST_CUT_MARGIN = 0.1
"""The line across the wrist that the forearm is cut at lies this fraction of the palm's
length beyond the palm's proximal face (a real wrist is wider than the palm slab ends)."""
MAX_FINGER_OUTSIDE = 0.35
"""Default excess of a finger's model pixels over the backdrop over the first frame."""
MAX_HIDDEN_UNEXPLAINED = 0.05
"""Default share of the pixels where a hidden digit would lie open that may be
unexplained foreground (chosen on the tracking model's own drawing, docs/accuracy.md)."""
SEEN_END_SHARE = 0.02
"""A digit's end (distal link and tip) is shown in a camera when it makes up at least this
share of the digit's drawn pixels there (a straight index seen from above its back: 0.12;
curled under the palm: 0)."""


@dataclass(frozen=True)
class WorkingImage:
    """One camera's image as the rule works on it (:data:`CHECK_MAX_SIDE`): ``grey``
    (H, W) and, for a colour image with the colour model on, ``colour`` (H, W, 3) RGB."""

    grey: np.ndarray
    colour: np.ndarray | None = None


@dataclass(frozen=True)
class SilhouetteLossOptions:
    """The silhouette rule's settings, shared by every tracker's options class (which
    inherits them, so ``--option silhouette_check=false`` works for any tracker).

    silhouette_check : apply the rule (it needs a plain backdrop and a static camera).
    silhouette_tolerance_px : silhouette differences within this distance are ignored, px
        of the checked images (at most :data:`CHECK_MAX_SIDE` wide).
    max_unexplained, max_finger_outside : the thresholds (fractions, excess over the first
        frame).
    max_hidden_unexplained : the hidden-digit threshold (a fraction; 1 turns the rule off).
    flag_hidden_fingers : also flag a digit whose end the estimate hides in every checked
        camera while it showed at the start state (where a hidden finger lies, no
        silhouette can say).
    judge_curled_digits : apply the hidden-digit test (``max_hidden_unexplained``) to
        every digit that showed at the start state, not only to those the estimate
        hides: a finger held curled in view while the real one is open is caught too.
    colour_foreground : over a textured backdrop, where no grey threshold separates the
        hand, find it in colour images by a colour model learned on the first frame
        (:mod:`~digiteyes.features.colour_foreground`; the camera stays unchecked when
        the model does not separate that frame).
    """

    silhouette_check: bool = True
    silhouette_tolerance_px: int = TOLERANCE_PX
    max_unexplained: float = MAX_UNEXPLAINED
    max_finger_outside: float = MAX_FINGER_OUTSIDE
    max_hidden_unexplained: float = MAX_HIDDEN_UNEXPLAINED
    flag_hidden_fingers: bool = False
    judge_curled_digits: bool = False
    colour_foreground: bool = True


@dataclass(frozen=True)
class SilhouetteVerdict:
    """One frame's silhouette rule: ``reasons`` (empty when the track holds),
    ``finger_lost`` (digit -> bool, the digits judged), ``checks`` (one per checked
    camera), ``hidden_shown`` (the digits the estimate hides, or with
    ``judge_curled_digits`` holds curled, while the image shows them where they would lie
    open: the hidden-digit test's)."""

    reasons: list[str]
    finger_lost: dict[str, bool]
    checks: list[SilhouetteCheck]
    hidden_shown: tuple[str, ...] = ()


class SilhouetteLoss:
    """The silhouette loss rule of one track (module docstring).

    Parameters
    ----------
    model, rig : the tracking model and its cameras.
    tolerance_px : silhouette differences within this distance are ignored, px of the
        checked images (at most :data:`CHECK_MAX_SIDE` wide).
    max_unexplained, max_finger_outside : the thresholds (fractions, excess over the
        first frame).
    max_hidden_unexplained : the hidden-digit threshold (a fraction in (0, 1]; 1 turns
        the rule off).
    flag_hidden_fingers : flag every digit the estimate hides (module docstring).
    judge_curled_digits : the hidden-digit test for every digit, hidden or not (module
        docstring).
    colour_foreground : the colour model over a textured backdrop (module docstring).

    Raises :class:`~digiteyes.errors.DigitEyesError` for a negative or non-integer
    tolerance or a threshold that is not positive.
    """

    def __init__(self, model: KinematicModel, rig: Rig, tolerance_px: int = TOLERANCE_PX,
                 max_unexplained: float = MAX_UNEXPLAINED,
                 max_finger_outside: float = MAX_FINGER_OUTSIDE,
                 max_hidden_unexplained: float = MAX_HIDDEN_UNEXPLAINED,
                 flag_hidden_fingers: bool = False, judge_curled_digits: bool = False,
                 colour_foreground: bool = True) -> None:
        if isinstance(tolerance_px, bool) or not isinstance(tolerance_px, int | np.integer) \
                or tolerance_px < 0:
            raise DigitEyesError(f"silhouette_tolerance_px must be an integer >= 0, got "
                                 f"{tolerance_px!r}")
        for name, value in (("max_unexplained", max_unexplained),
                            ("max_finger_outside", max_finger_outside)):
            if not value > 0:
                raise DigitEyesError(f"{name} must be positive, got {value!r}")
        if not 0 < max_hidden_unexplained <= 1:
            raise DigitEyesError(f"max_hidden_unexplained must lie in (0, 1], got "
                                 f"{max_hidden_unexplained!r}")
        self.model, self.rig = model, rig
        self._rig = Rig(tuple(resized_camera(c, *working_size(c.width, c.height,
                                                               CHECK_MAX_SIDE)) for c in rig))
        """The cameras of the images the rule works on (:data:`CHECK_MAX_SIDE`)."""
        self.tolerance_px = tolerance_px
        self.max_unexplained = max_unexplained
        self.max_finger_outside = max_finger_outside
        self.max_hidden_unexplained = max_hidden_unexplained
        self.flag_hidden_fingers = flag_hidden_fingers
        self.judge_curled_digits = judge_curled_digits
        self.colour_foreground = colour_foreground
        self._digit_links = digit_links(model)
        self._palm = next((link for link in model.links if link.kind == "palm"), None)
        self._digit_ends = {d: np.array([i for i, link in enumerate(model.links)
                                         if link.name in (f"{d}.distal", f"{d}.tip")], dtype=int)
                            for d in DIGITS}
        self.reset()

    @classmethod
    def from_options(cls, model: KinematicModel, rig: Rig,
                     options: SilhouetteLossOptions) -> SilhouetteLoss:
        """The rule with the settings of a tracker's options."""
        return cls(model, rig, options.silhouette_tolerance_px, options.max_unexplained,
                   options.max_finger_outside, options.max_hidden_unexplained,
                   options.flag_hidden_fingers, options.judge_curled_digits,
                   options.colour_foreground)

    def reset(self) -> None:
        """Forget the foreground and the baseline: the next :meth:`check` fits them."""
        self.foreground: list[Foreground | ColourForeground | None] | None = None
        self.rebaseline()

    def rebaseline(self) -> None:
        """Forget the baselines but keep the foreground (a tracker restarted in the same
        scene after a re-detection): the next :meth:`check` measures them at its
        reference state."""
        self._unexplained_baseline: dict[int, float] | None = None
        self._hand_side_baseline: dict[int, float] = {}
        self._outside_baseline: dict[int, dict[str, float]] = {}
        self._shown_baseline: set[str] = set()

    def check(self, images: Sequence[np.ndarray], state: np.ndarray,
              reference: np.ndarray, colours: Sequence[np.ndarray] | None = None
              ) -> SilhouetteVerdict:
        """The rule for one frame: ``images`` (H, W) grey (any image type is made grey),
        one per camera in rig order, the estimated ``state`` (n_q,), and ``reference``
        (n_q,), the state the track started from (used on the first frame after a reset:
        the foreground is fitted, and the baselines measured, at that state, so that an
        estimate already wrong in the first frame is not taken as the norm).
        ``colours``: the same frames as they came (RGB where in colour), for the colour
        model over a textured backdrop."""
        images = self._working_images(images, colours)
        if self.foreground is None:
            kin0 = forward_kinematics(self.model, reference)
            self.foreground = [self._fit(image, model_labels(self.model, kin0, camera))
                               for image, camera in zip(images, self._rig, strict=True)]
        if self._unexplained_baseline is None:
            kin0 = forward_kinematics(self.model, reference)
            baseline = self._checks(images, kin0)
            self._unexplained_baseline = {c.camera: c.unexplained for c in baseline}
            self._outside_baseline = {c.camera: dict(c.finger_outside) for c in baseline}
            self._shown_baseline = {d for d in self._digit_links if self.end_shown(d, baseline)}
            self._hand_side_baseline = {
                c.camera: value for c in baseline if not self._judged_whole(c)
                and (value := self._unexplained_hand_side(c, kin0)) is not None}
        kin = forward_kinematics(self.model, state)
        checks = self._checks(images, kin)
        reasons, fingers, shown = self._reasons(checks, state, kin)
        return SilhouetteVerdict(reasons, fingers, checks, shown)

    def mismatch(self, images: Sequence[np.ndarray], state: np.ndarray,
                 colours: Sequence[np.ndarray] | None = None) -> float | None:
        """How badly ``state`` (n_q,) explains the hand's silhouette in ``images`` (any
        image type, one per camera; ``colours`` as for :meth:`check`): per checked
        camera, the hand pixels it leaves unexplained per model pixel plus the mean share
        of its fingers' pixels over the backdrop, summed over the cameras. None before
        the first :meth:`check` or when no camera is checked."""
        scores = self.mismatches(images, [state], colours=colours)
        return None if scores is None else scores[0]

    def mismatches(self, images: Sequence[np.ndarray], states: Sequence[np.ndarray],
                   symmetric: bool = False, colours: Sequence[np.ndarray] | None = None
                   ) -> list[float] | None:
        """:meth:`mismatch` of each of ``states`` (the foreground masks found once). With
        ``symmetric``, the second term is instead the share of all the model's pixels
        over the backdrop: the symmetric difference of the two silhouettes per model
        pixel, in which a finger hidden behind the palm does not drop out (its real
        pixels are left unexplained), as it does from the mean over the fingers seen. None,
        too, when no camera can be judged with the images given (a colour camera without
        its colour frame)."""
        if not self.foreground or all(fg is None for fg in self.foreground):
            return None
        masks = self._masks(self._working_images(images, colours))
        if all(mask is None for mask in masks):  # colour cameras given no colour frames
            return None
        scores = []
        for state in states:
            checks = self._checks_masks(masks, forward_kinematics(self.model, state))
            scores.append(float(sum(
                c.unexplained + (c.outside if symmetric else
                                 np.mean(list(c.finger_outside.values()))
                                 if c.finger_outside else 0.0)
                for c in checks)))
        return scores

    def _working_images(self, images: Sequence[np.ndarray],
                        colours: Sequence[np.ndarray] | None) -> list[WorkingImage]:
        """Each camera's image at the rule's size (:data:`CHECK_MAX_SIDE`): the grey
        levels of ``images`` (made grey, then resized), and the colours of ``colours``
        where a frame is in colour and the colour model is on (or still to be fitted)."""
        greys = resize_images([prepare_image(image) for image in images], self._rig)
        wanted = colours is not None and self.colour_foreground and (
            self.foreground is None
            or any(isinstance(fg, ColourForeground) for fg in self.foreground))
        if not wanted or not any(is_colour(image) for image in colours):
            return [WorkingImage(grey) for grey in greys]
        resized = resize_images(list(colours), self._rig)
        return [WorkingImage(grey, colour if is_colour(colour) else None)
                for grey, colour in zip(greys, resized, strict=True)]

    def _fit(self, image: WorkingImage, labels: np.ndarray
             ) -> Foreground | ColourForeground | None:
        """The grey foreground of the first frame; else (a busy backdrop) its colour model
        when the image is in colour, the option is on and the model splits the frame;
        else the grey foreground through the noise blur (a noisy sensor,
        :func:`~digiteyes.features.foreground.fit_foreground`); else None."""
        grey = fit_foreground(image.grey, labels, noise_blur_px=0.0)
        if grey is not None:
            return grey
        colour = (None if image.colour is None else
                  fit_colour_foreground(image.colour, labels, MARGIN_PX))
        return colour if colour is not None else fit_foreground(image.grey, labels)

    def _masks(self, images: Sequence[WorkingImage]) -> list[np.ndarray | None]:
        """The foreground mask of each camera's image (None where not checked)."""
        return [None if fg is None else
                fg.mask(image.grey) if not isinstance(fg, ColourForeground) else
                None if image.colour is None else fg.mask(image.colour)
                for image, fg in zip(images, self.foreground, strict=True)]

    def _checks_masks(self, masks: list[np.ndarray | None], kin: Kinematics
                      ) -> list[SilhouetteCheck]:
        """The silhouette comparison in every camera with a mask, each marked with its
        camera's index."""
        return [replace(silhouette_check(self.model, kin, camera, mask, self.tolerance_px),
                        camera=i)
                for i, (mask, camera) in enumerate(zip(masks, self._rig, strict=True))
                if mask is not None]

    def _checks(self, images: Sequence[WorkingImage], kin: Kinematics
                ) -> list[SilhouetteCheck]:
        """The silhouette comparison in every camera whose foreground could be fitted."""
        return self._checks_masks(self._masks(images), kin)

    def hidden_digits(self, checks: Sequence[SilhouetteCheck]) -> list[str]:
        """The digits whose end showed at the start state and that the estimate of
        ``checks`` hides in every checked camera."""
        return [d for d in DIGITS
                if d in self._shown_baseline and not self.end_shown(d, checks)]

    def unexplained_where_open(self, checks: Sequence[SilhouetteCheck], state: np.ndarray,
                               digits: Sequence[str]) -> dict[str, float]:
        """Per digit of ``digits``: the largest share, over the checked cameras, of the
        pixels where it would lie open (beyond the estimate ``state`` of ``checks``) that
        are unexplained foreground (cameras where it would lie over the estimate left
        out; digits with no such camera left out)."""
        if not digits:
            return {}
        kin = forward_kinematics(self.model, open_digits(self.model, state, digits))
        shares: dict[str, float] = {}
        for check in checks:
            labels = model_labels(self.model, kin, self._rig[check.camera])
            for digit in digits:
                share = unexplained_where_open(check, labels, self._digit_links[digit])
                if share is not None:
                    shares[digit] = max(share, shares.get(digit, 0.0))
        return shares

    def _judged_whole(self, check: SilhouetteCheck) -> bool:
        """Whether ``check``'s camera is judged by all its unexplained pixels: a grey
        camera, or a colour camera whose start left at most
        :data:`MAX_START_UNEXPLAINED` unexplained."""
        base = (self._unexplained_baseline or {}).get(check.camera, 0.0)
        return base <= MAX_START_UNEXPLAINED or not isinstance(
            self.foreground[check.camera], ColourForeground)

    def _unexplained_hand_side(self, check: SilhouetteCheck, kin: Kinematics
                               ) -> float | None:
        """``check``'s unexplained foreground per model pixel, counting only the pixels
        on the hand's side of the line across the palm's long axis
        :data:`WRIST_CUT_MARGIN` beyond the wrist of the pose ``kin`` (the forearm, which the
        model lacks, cut away); None without a palm link or pixels to count."""
        if self._palm is None or check.unexplained_mask is None or not check.model_pixels:
            return None
        centre = np.asarray(self._palm.centre, dtype=float)
        half_length = np.array([0.0, 0.5 * float(self._palm.size[1]), 0.0])
        ends = np.array([centre - (1.0 + 2.0 * WRIST_CUT_MARGIN) * half_length,
                         centre + half_length])
        T = kin.T_world_shape[0, self._palm.row]
        wrist, distal = self._rig[check.camera].project(ends @ T[:3, :3].T + T[:3, 3])
        rows, cols = check.box
        vs, us = np.nonzero(check.unexplained_mask)
        along = ((us + cols.start - wrist[0]) * (distal[0] - wrist[0])
                 + (vs + rows.start - wrist[1]) * (distal[1] - wrist[1]))
        return float(np.count_nonzero(along >= 0.0)) / check.model_pixels

    def _reasons(self, checks: list[SilhouetteCheck], state: np.ndarray, kin: Kinematics
                 ) -> tuple[list[str], dict[str, bool], tuple[str, ...]]:
        reasons: list[str] = []
        fingers: dict[str, bool] = {}
        for check in checks:
            base = self._unexplained_baseline.get(check.camera)
            if base is None:  # not checked at the start state: nothing to compare with
                continue
            outside_base = self._outside_baseline[check.camera]
            if self._judged_whole(check):
                if check.unexplained - base > self.max_unexplained:
                    reasons.append(f"camera {check.camera}: {check.unexplained:.0%} of the "
                                   f"model's area of the hand unexplained (at the start "
                                   f"state {base:.0%})")
            elif (start := self._hand_side_baseline.get(check.camera)) is not None and (
                    now := self._unexplained_hand_side(check, kin)) is not None and (
                    now - start > self.max_unexplained):
                reasons.append(f"camera {check.camera}: {now:.0%} of the model's area of the "
                               f"hand unexplained on the hand's side of the wrist (at the "
                               f"start state {start:.0%})")
            for finger, outside in check.finger_outside.items():
                excess = outside - outside_base.get(finger, 0.0)
                fingers[finger] = fingers.get(finger, False) or excess > self.max_finger_outside
        off = [finger for finger, lost in fingers.items() if lost]
        if off:
            reasons.append(f"off the hand's silhouette: {', '.join(off)}")
        hidden = self.hidden_digits(checks) if checks else []
        shown: dict[str, float] = {}
        if self.max_hidden_unexplained < 1:
            judged = ([d for d in DIGITS if d in self._shown_baseline]
                      if self.judge_curled_digits and checks else hidden)
            shares = self.unexplained_where_open(checks, state, judged)
            shown = {d: v for d, v in shares.items() if v > self.max_hidden_unexplained}
            for digit in shown:
                fingers[digit] = True
            for label, names in (("hidden by the estimate", [d for d in shown if d in hidden]),
                                 ("curled by the estimate", [d for d in shown
                                                             if d not in hidden])):
                if names:
                    reasons.append(f"{label} while the image shows it: " + ", ".join(
                        f"{d} ({shown[d]:.0%} of where it would lie open unexplained)"
                        for d in names))
        if self.flag_hidden_fingers and hidden:
            for digit in hidden:
                fingers[digit] = True
            reasons.append(f"hidden, so unverified: {', '.join(hidden)}")
        return reasons, fingers, tuple(shown)

    def end_shown(self, digit: str, checks: Sequence[SilhouetteCheck]) -> bool:
        """Whether the end of ``digit`` (distal link and tip) shows in some camera of
        ``checks``: at least :data:`SEEN_END_SHARE` of the digit's drawn pixels there. A
        digit the model lacks counts as shown."""
        links, ends = self._digit_links.get(digit), self._digit_ends.get(digit)
        if links is None or ends is None or not len(ends):
            return True
        for check in checks:
            if check.link_pixels is None:
                continue
            total = float(check.link_pixels[links].sum())
            if total > 0 and check.link_pixels[ends].sum() >= SEEN_END_SHARE * total:
                return True
        return False
