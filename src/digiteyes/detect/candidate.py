"""What a hand detector returns, and the protocol every detector follows."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Protocol, runtime_checkable

import numpy as np

from digiteyes.camera import Camera
from digiteyes.camera.mirror import unmirror_pixels, unmirror_points
from digiteyes.detect.hand21 import HAND21_NAMES


@dataclass(frozen=True)
class HandCandidate:
    """One hand found in one image.

    Attributes
    ----------
    keypoints : (21, 2) pixel positions in :data:`~digiteyes.detect.hand21.HAND21_NAMES`
        order (pixel (0, 0) is the centre of the top-left pixel).
    keypoint_confidence : (21,) in [0, 1]; 0 for a keypoint the detector only guessed.
    confidence : overall confidence in [0, 1] that this is a hand.
    bbox : ``(x0, y0, x1, y1)`` pixels, the box holding the hand.
    handedness : ``"right"``, ``"left"`` or ``None`` when the detector cannot tell.
    detector : name of the detector that produced it.
    keypoints_3d : optional (21, 3) metric points the detector estimates (MediaPipe's world
        landmarks: metres converted to mm, origin near the hand's centre, not the camera).
    mask : optional bool (H, W) segmentation of the hand.
    """

    keypoints: np.ndarray
    keypoint_confidence: np.ndarray
    confidence: float
    bbox: tuple[float, float, float, float]
    handedness: str | None
    detector: str
    keypoints_3d: np.ndarray | None = None
    mask: np.ndarray | None = None

    names: tuple[str, ...] = HAND21_NAMES

    def mirrored(self, width: int) -> HandCandidate:
        """The same hand in the image flipped left to right (``width`` px): pixels, box
        and side mirrored (:mod:`digiteyes.camera.mirror`); 3D points and mask too."""
        keypoints = unmirror_pixels(self.keypoints, width)
        x0, y0, x1, y1 = self.bbox
        side = {"right": "left", "left": "right"}.get(self.handedness or "")
        points = None if self.keypoints_3d is None else unmirror_points(self.keypoints_3d)
        return replace(self, keypoints=keypoints, bbox=(width - 1 - x1, y0, width - 1 - x0, y1),
                       handedness=side, keypoints_3d=points,
                       mask=None if self.mask is None else self.mask[:, ::-1].copy())

    def unturned(self, quarter_turns: int, width: int, height: int) -> HandCandidate:
        """The same hand in the image before it was turned clockwise by ``quarter_turns``
        quarter turns (``numpy.rot90(image, -quarter_turns)``; ``width`` x ``height`` px
        is the size of the image before the turn). Pixels, box and mask are turned back;
        3D points, whose x and y axes follow the image's (MediaPipe's world landmarks),
        are turned back about their z axis. The side is kept: a turn is not a mirror."""
        turns = quarter_turns % 4
        keypoints = _turned_back(self.keypoints, turns, width, height)
        x0, y0, x1, y1 = self.bbox
        corners = _turned_back(np.array([[x0, y0], [x1, y1]]), turns, width, height)
        points = None
        if self.keypoints_3d is not None:  # a vector turns as a pixel of a 1 x 1 image
            xyz = np.asarray(self.keypoints_3d, dtype=float)
            points = np.column_stack([_turned_back(xyz[:, :2], turns, 1, 1), xyz[:, 2]])
        mask = None if self.mask is None else np.ascontiguousarray(np.rot90(self.mask, turns))
        return replace(self, keypoints=keypoints, bbox=bbox_of(corners), keypoints_3d=points,
                       mask=mask)

    def to_json(self) -> dict:
        """A JSON-ready dict (no mask)."""
        out = {"detector": self.detector, "confidence": float(self.confidence),
               "handedness": self.handedness, "bbox_px": [float(v) for v in self.bbox],
               "keypoints_px": {n: [float(u), float(v)] for n, (u, v)
                                in zip(self.names, self.keypoints, strict=True)},
               "keypoint_confidence": {n: float(c) for n, c
                                       in zip(self.names, self.keypoint_confidence,
                                              strict=True)}}
        return out


def _turned_back(points: np.ndarray, turns: int, width: int, height: int) -> np.ndarray:
    """Where pixels (P, 2) of an image turned clockwise by ``turns`` quarter turns lie in
    the image before the turn (``width`` x ``height`` px)."""
    u, v = np.asarray(points, dtype=float).T
    back = ((u, v), (v, height - 1 - u), (width - 1 - u, height - 1 - v),
            (width - 1 - v, u))[turns]
    return np.column_stack(back)


def bbox_of(points: np.ndarray, margin: float = 0.0) -> tuple[float, float, float, float]:
    """The box ``(x0, y0, x1, y1)`` round pixel points (P, 2), grown by ``margin`` px."""
    points = np.asarray(points, dtype=float)
    x0, y0 = points.min(0) - margin
    x1, y1 = points.max(0) + margin
    return float(x0), float(y0), float(x1), float(y1)


@runtime_checkable
class HandDetector(Protocol):
    """Anything that finds hands in an image.

    ``detect(image, camera)`` takes an RGB uint8 (H, W, 3) or grey (H, W) image and the
    camera that took it (detectors may ignore it) and returns the candidates, best first.
    ``locates_joints`` says whether its keypoints are joints found in the image (a learned
    detector) rather than placed by a model on a silhouette: only the former can measure
    the user's link lengths (:mod:`digiteyes.detect.link_lengths`).
    """

    name: str
    locates_joints: bool

    def detect(self, image: np.ndarray, camera: Camera | None = None) -> list[HandCandidate]:
        """Hand candidates in ``image``, best first (an empty list when there is none)."""
        ...
