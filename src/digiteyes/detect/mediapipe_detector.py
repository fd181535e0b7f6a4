"""MediaPipe Hands (Zhang et al. 2020) as a digiteyes detector: an optional extra.

``pip install "digiteyes[mediapipe]"`` installs ``mediapipe==0.10.14``, whose wheel carries
the palm-detection and landmark models, so nothing is downloaded at run time. Without it,
creating the detector raises :class:`~digiteyes.errors.DigitEyesError` saying how to
install it.

MediaPipe labels handedness as seen in a mirrored selfie image; we report the anatomical
side for an unmirrored camera image (its "Left" label is a right hand).

MediaPipe's native code writes start-up notices straight to the process's standard error
("Created TensorFlow Lite XNNPACK delegate", "Feedback manager requires a model with a
single signature", one set per graph) where they break up the command's own output and
progress bar. The graph's threads write them while it starts, after the constructor has
returned, so the constructor builds the graph and runs it once on a blank image with
those notices silenced (:func:`quiet_native_stderr`); later messages, and every Python
error, pass as usual.

**Grey images.** MediaPipe's palm detector was trained on colour photographs and leans
on the skin's hue: on a grey image (a monochrome camera like the thesis's, a grey
dataset) it misses hands it finds in colour. So in a grey image (2-D, or three nearly
equal channels, :func:`is_grey`) in which it finds no hand it looks once more, at the
image given a skin hue (:func:`skin_tinted`; ``grey_as_skin``, on by default); the
keypoints are the same pixels either way. On real images made grey (the real video every
6th frame, the annotated images and the STB pair; docs/initialisation.md) it then finds
112 of the 126 hands, against 86 in grey alone and 103 with every image tinted; and
where grey already works the tint throughout does not make the keypoints better (the
real video made grey, tracked: 3.8 px from the colour video's track in the median frame
against 3.7 with the rule; ``benchmarks/real_grey.py``). On the synthetic webcam's dim
flesh hand in grey: 0 of 20 frames, 12 with the tint.

**Hands held sideways or upside down.** The palm detector also misses some hands that it
finds once the image is turned: of the 20 annotated real images (``../shared/data``),
one FreiHAND hand only a quarter turn clockwise, and InterHand's grey thumbs-up only a
quarter or a half turn. So in still-image mode, an image in which no hand is found is
looked at again turned a quarter turn clockwise, then anticlockwise, then by a half turn
(:data:`TURNS`), until one finds a hand; its keypoints and 3D points are turned back
(:meth:`~digiteyes.detect.candidate.HandCandidate.unturned`; ``look_turned``, on by
default). An image without a hand then costs four looks instead of one. For single
images only (``pose``, ``calibrate-hand``): the automatic start and the re-detections of
a track look at frames of footage without turning them
(:func:`~digiteyes.detect.pose.make_detector`'s ``look_turned``), because there a miss
costs one frame and a false find a wrong start, and the turned looks find more false
hands: on the dim webcam render's first frames, where MediaPipe finds no hand upright,
one fitted a whole hand onto the thumb (a start 420 mm off, where the classic detector's
is 14 mm off). Video mode never turns: MediaPipe follows each hand from its landmarks in
the frame before, which a turned frame would break.
"""

from __future__ import annotations

import contextlib
import os
import sys
import warnings
import weakref
from collections.abc import Iterator

import cv2
import numpy as np

from digiteyes.camera import Camera
from digiteyes.detect.candidate import HandCandidate, bbox_of
from digiteyes.errors import DigitEyesError

BLANK_SIDE = 64
"""Side (px) of the blank image a new graph runs once to start (module docstring)."""
INSTALL_HINT = ('the MediaPipe detector needs the optional extra: pip install '
                '"digiteyes[mediapipe]" (mediapipe==0.10.14, models included); or use '
                '--detector classic')
GREY_SKIN_RGB = (1.32, 0.90, 0.69)
"""The skin hue :func:`skin_tinted` gives a grey level: the median colour of the real
video's hand (RGB ratio 1 : 0.68 : 0.52, sampled inside the palm in 21 frames), scaled so
that its luma (ITU-R BT.601 weights) is 1, which keeps every pixel's grey level."""


@contextlib.contextmanager
def quiet_native_stderr() -> Iterator[None]:
    """Send what native code writes to file descriptor 2 to the null device for the
    duration of the block (Python's own ``sys.stderr`` is flushed first and restored
    after, so nothing of ours is lost or reordered)."""
    sys.stderr.flush()
    try:
        saved = os.dup(2)
    except OSError:  # no standard error to redirect (a detached process)
        yield
        return
    try:
        with open(os.devnull, "wb") as null:
            os.dup2(null.fileno(), 2)
        yield
    finally:
        sys.stderr.flush()
        os.dup2(saved, 2)
        os.close(saved)


def mediapipe_available() -> bool:
    """True when ``mediapipe`` imports."""
    try:
        import mediapipe  # noqa: F401
    except ImportError:
        return False
    return True


GREY_SPREAD = 4
"""The largest difference (grey levels) between an RGB pixel's channels that still counts
as grey: a grey video compressed with chroma subsampling (H.264, MPEG-4) decodes with
channels up to 2 levels apart."""


def is_grey(image: np.ndarray) -> bool:
    """Whether a uint8 image holds grey levels only: 2-D, or RGB whose channels differ by
    at most :data:`GREY_SPREAD` in 99 % of its pixels (every 8th row and column looked
    at)."""
    if image.ndim == 2:
        return True
    if image.ndim != 3 or image.shape[2] != 3:
        return False
    sample = image[::8, ::8].astype(np.int16)
    spread = sample.max(axis=2) - sample.min(axis=2)
    return bool(np.count_nonzero(spread > GREY_SPREAD) <= 0.01 * spread.size)


_SKIN_TABLES = [np.ascontiguousarray(channel) for channel in np.clip(np.rint(
    np.arange(256.0)[:, None] * np.asarray(GREY_SKIN_RGB)), 0, 255).astype(np.uint8).T]
"""Per RGB channel, the lookup table (256,) uint8 of :func:`skin_tinted`."""

TURNS = (1, 3, 2)
"""Quarter turns clockwise of the image's second looks in still-image mode (module
docstring): a quarter turn either way before the half turn, since hands held sideways are
commoner than hands upside down."""


def skin_tinted(grey: np.ndarray) -> np.ndarray:
    """An RGB uint8 (H, W, 3) image whose pixels have the grey levels of ``grey`` (H, W)
    uint8 and the hue :data:`GREY_SKIN_RGB` (clipped at 255 in the red channel above
    grey level 193)."""
    return cv2.merge([cv2.LUT(grey, table) for table in _SKIN_TABLES])


def _read_only(image: np.ndarray) -> np.ndarray:
    """A C-contiguous read-only view of ``image`` (a copy only when it is not contiguous).
    MediaPipe wraps a read-only array without copying it (``packet_creator.
    create_image_frame``'s reference mode) and copies a writable one; the graph has
    finished with it when ``process`` returns, so sharing is safe."""
    view = np.ascontiguousarray(image).view()
    view.flags.writeable = False
    return view


class MediaPipeDetector:
    """Hands by MediaPipe's palm detector and landmark network (CPU, TFLite).

    Parameters
    ----------
    max_hands : hands to return at most.
    static_image_mode : True treats every image alone (``pose``); False lets MediaPipe
        track landmarks between consecutive video frames (faster, smoother).
    min_confidence : detection confidence below which MediaPipe drops a hand.
    model_complexity : 0 (lite) or 1 (full) landmark network.
    grey_as_skin : in a grey image without a hand, look again with the image tinted to
        skin (module docstring).
    look_turned : in still-image mode, in an image without a hand, look again at it
        turned by quarter turns (:data:`TURNS`, module docstring); ignored in video mode.
    """

    name = "mediapipe"
    locates_joints = True  # keypoints from a network trained on annotated joints

    def __init__(self, max_hands: int = 2, static_image_mode: bool = True,
                 min_confidence: float = 0.5, model_complexity: int = 1,
                 grey_as_skin: bool = True, look_turned: bool = True) -> None:
        try:
            import mediapipe as mp
        except ImportError as exc:
            raise DigitEyesError(f"{INSTALL_HINT} ({exc})") from None
        self.grey_as_skin = grey_as_skin
        self.look_turned = look_turned and static_image_mode
        with quiet_native_stderr(), warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            self._hands = mp.solutions.hands.Hands(
                static_image_mode=static_image_mode, max_num_hands=max_hands,
                model_complexity=model_complexity, min_detection_confidence=min_confidence,
                min_tracking_confidence=min_confidence)
            self._hands.process(np.zeros((BLANK_SIDE, BLANK_SIDE, 3), np.uint8))  # graph started
        # MediaPipe does not stop a graph its object no longer reaches (about 75 MB each,
        # kept to the end of the process): the detector stops it when it is itself
        # collected, or at close(), whichever comes first
        self._release = weakref.finalize(self, self._hands.close)

    def close(self) -> None:
        """Release MediaPipe's graph now (it is released anyway when the detector is
        garbage-collected); idempotent."""
        self._release()

    def detect(self, image: np.ndarray, camera: Camera | None = None) -> list[HandCandidate]:
        """Hands in an RGB (H, W, 3) or grey (H, W) uint8 image, most confident first (in a
        grey image where MediaPipe finds none, those it finds once the image is tinted to
        skin, ``grey_as_skin``; then, in still-image mode, those it finds in the image
        turned, ``look_turned``)."""
        image = np.asarray(image)
        if image.dtype != np.uint8 or image.ndim not in (2, 3) or (
                image.ndim == 3 and image.shape[2] != 3):
            raise DigitEyesError(f"MediaPipe detector: expected a uint8 RGB or grey image, got "
                                 f"{image.dtype} {image.shape}")
        if image.ndim == 2:
            image = np.repeat(image[..., None], 3, axis=2)
        found = self._detect_rgb(image)
        if not found and self.grey_as_skin and is_grey(image):
            image = skin_tinted(cv2.cvtColor(image, cv2.COLOR_RGB2GRAY))
            found = self._detect_rgb(image)
        if not found and self.look_turned:
            found = self._detect_turned(image)
        return found

    def _detect_turned(self, image: np.ndarray) -> list[HandCandidate]:
        """Hands in ``image`` turned by each of :data:`TURNS` in turn, until one finds
        any, in the coordinates of ``image``."""
        height, width = image.shape[:2]
        for turns in TURNS:
            found = self._detect_rgb(np.rot90(image, -turns))
            if found:
                return [c.unturned(turns, width, height) for c in found]
        return []

    def _detect_rgb(self, image: np.ndarray) -> list[HandCandidate]:
        """Hands in an RGB (H, W, 3) uint8 image, most confident first."""
        height, width = image.shape[:2]
        with warnings.catch_warnings():  # protobuf's deprecation notice inside MediaPipe
            warnings.simplefilter("ignore", UserWarning)
            result = self._hands.process(_read_only(image))
        if not result.multi_hand_landmarks:
            return []
        worlds = result.multi_hand_world_landmarks or [None] * len(result.multi_hand_landmarks)
        found = []
        for marks, world, side in zip(result.multi_hand_landmarks, worlds,
                                      result.multi_handedness, strict=True):
            # normalised [0, 1] coordinates measure from the image's outer edge
            uv = np.array([[m.x * width - 0.5, m.y * height - 0.5] for m in marks.landmark])
            label = side.classification[0]
            xyz = None if world is None else 1000.0 * np.array(
                [[m.x, m.y, m.z] for m in world.landmark])
            found.append(HandCandidate(
                keypoints=uv, keypoint_confidence=np.full(21, float(label.score)),
                confidence=float(label.score), bbox=bbox_of(uv, 10.0),
                handedness="right" if label.label == "Left" else "left",
                detector=self.name, keypoints_3d=xyz))
        found.sort(key=lambda c: -c.confidence)
        return found
