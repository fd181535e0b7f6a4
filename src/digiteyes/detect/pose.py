"""Hand pose from single images: detection, then the model fit, per image or camera set.

:func:`estimate_pose` is what ``digiteyes pose`` runs for each image (one camera) or each
set of simultaneous images (a rig). :func:`make_detector` creates a detector by name.
"""

from __future__ import annotations

import csv
import json
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from digiteyes.camera import Rig
from digiteyes.camera.mirror import unmirror_points
from digiteyes.detect.candidate import HandCandidate, HandDetector
from digiteyes.detect.hand21 import HAND21_NAMES
from digiteyes.detect.model_fit import FitOptions, KeypointObservation, PoseFit, fit_keypoints
from digiteyes.detect.side import is_other_hand, pick_candidate
from digiteyes.errors import DigitEyesError
from digiteyes.kinematics import KinematicModel

DETECTORS = ("auto", "mediapipe", "mediapipe-lite", "classic")
"""Detector names of :func:`make_detector` (and of every command's ``--detector``)."""


def make_detector(name: str, model: KinematicModel | None = None,
                  video: bool = False, classic_fallback: bool = False,
                  max_hands: int = 1, look_turned: bool = True,
                  remember_side: bool = False) -> HandDetector:
    """``"mediapipe"`` (needs the extra; its full landmark network), ``"mediapipe-lite"``
    (its lite landmark network: faster, see docs/initialisation.md for what it costs),
    ``"classic"`` or ``"auto"`` (MediaPipe when installed, else classic). ``video``:
    images come in order from one video, and MediaPipe follows its landmarks from one to
    the next instead of detecting afresh in each (the classic detector has no such mode).
    ``classic_fallback``: ``"auto"`` with MediaPipe installed asks the classic detector
    in the images where MediaPipe finds no hand
    (:class:`~digiteyes.detect.fallback.FallbackDetector`); what ``track`` and ``pose``
    use, not ``calibrate-hand``, which measures segments from joints a network located.
    ``max_hands``: hands MediaPipe returns at most (the classic detector finds one); more
    than one lets the caller pick the tracked hand (:mod:`digiteyes.detect.side`).
    ``look_turned``: MediaPipe in still-image mode looks again at an image without a hand
    turned by quarter turns (:mod:`~digiteyes.detect.mediapipe_detector`); on for single
    images, off for frames of footage (:class:`~digiteyes.detect.initialiser.
    AutoInitialiser`), where a miss costs a frame and a false find a wrong start.
    ``remember_side``: the images are frames of footage in order, and the classic
    detector keeps a camera's side of the hand where a silhouette cannot tell it
    (:class:`~digiteyes.detect.classic.ClassicDetector`)."""
    from digiteyes.detect.classic import ClassicDetector
    from digiteyes.detect.fallback import FallbackDetector
    from digiteyes.detect.mediapipe_detector import MediaPipeDetector, mediapipe_available

    if name == "auto" and classic_fallback and mediapipe_available():
        return FallbackDetector(make_detector("mediapipe", model, video, max_hands=max_hands,
                                              look_turned=look_turned),
                                ClassicDetector(model, remember_side=remember_side))
    if name == "auto":
        name = "mediapipe" if mediapipe_available() else "classic"
    if name in ("mediapipe", "mediapipe-lite"):
        return MediaPipeDetector(max_hands=max_hands, static_image_mode=not video,
                                 model_complexity=0 if name == "mediapipe-lite" else 1,
                                 look_turned=look_turned)
    if name == "classic":
        return ClassicDetector(model, remember_side=remember_side)
    raise DigitEyesError(f"unknown detector {name!r}; choose one of {', '.join(DETECTORS)}")


@dataclass
class PoseResult:
    """One image set's detections and fit (``fit`` is None when no camera found a hand).

    Attributes
    ----------
    candidates : per camera, the best candidate or None.
    fit : the model fit, or None.
    seconds : ``{"detect": s, "fit": s}`` wall time.
    fit_failure : why the detections could not be fitted (None when they were, or when
        no camera found a hand).
    other_hands : hands left out as the other side's (:mod:`digiteyes.detect.side`).
    """

    candidates: list[HandCandidate | None]
    fit: PoseFit | None
    seconds: dict[str, float]
    fit_failure: str | None = None
    other_hands: int = 0

    def sides(self, mirrored: bool = False) -> set[str]:
        """The sides of the hand (``"right"``, ``"left"``) the detectors reported, in the
        real images (``mirrored``: the detections were made in flipped ones, which show
        the other side); empty when no detector could tell."""
        flip = {"right": "left", "left": "right"}
        return {flip[c.handedness] if mirrored else c.handedness
                for c in self.candidates if c is not None and c.handedness in flip}


def estimate_pose(images: Sequence[np.ndarray], rig: Rig, detector: HandDetector,
                  model: KinematicModel, options: FitOptions | None = None,
                  side: str | None = None) -> PoseResult:
    """Detect the hand in each camera's image and fit ``model`` to all detections. Of
    several hands in an image the one of ``side`` is taken (None: any; the most confident
    of them, :func:`~digiteyes.detect.side.pick_candidate`)."""
    rig.check_images(images)
    start = time.perf_counter()
    candidates, other_hands = [], 0
    for image, camera in zip(images, rig, strict=True):
        found = detector.detect(image, camera)
        candidates.append(pick_candidate(found, side))
        other_hands += sum(side is not None and is_other_hand(c, side) for c in found)
    detected = time.perf_counter()
    observations = [KeypointObservation.of(c, cam)
                    for cam, c in zip(rig, candidates, strict=True) if c is not None]
    options = FitOptions() if options is None else options
    fit, failure = None, None
    if observations:
        try:
            fit = fit_keypoints(model, observations, options=options)
        except DigitEyesError as error:  # keypoints no pose of the hand explains
            failure = str(error)
    return PoseResult(candidates, fit, {"detect": detected - start,
                                        "fit": time.perf_counter() - detected}, failure,
                      other_hands)


def real_candidates(result: PoseResult, rig: Rig) -> list[HandCandidate | None]:
    """The detections in the real images (a mirrored rig's, :mod:`digiteyes.camera.mirror`,
    were made in flipped ones)."""
    if not rig.mirrored:
        return list(result.candidates)
    return [None if c is None else c.mirrored(cam.width)
            for cam, c in zip(rig, result.candidates, strict=True)]


def real_keypoints(points: np.ndarray, rig: Rig) -> np.ndarray:
    """Fitted points (..., 3) of the world or a camera frame of ``rig``, in the real scene
    (a mirrored rig's are reflected back)."""
    return unmirror_points(points) if rig.mirrored else np.asarray(points)


def pose_to_json(result: PoseResult, rig: Rig, sources: Sequence[str]) -> dict:
    """A JSON-ready record: detections, 3D keypoints (mm) in the world and in each camera,
    joint angles (deg), the scaled state, hand scale and timings. With a mirrored rig (a
    left hand) pixels and points are the real images' and scene's; the state is that of
    the mirror image's right hand."""
    out: dict = {"images": list(sources), "seconds": result.seconds,
                 "hand_side": "left" if rig.mirrored else "right",
                 "detections": {cam.name: None if c is None else c.to_json()
                                for cam, c in zip(rig, real_candidates(result, rig),
                                                  strict=True)}}
    fit = result.fit
    if fit is None:
        out["hand"] = None
        out["fit_failure"] = result.fit_failure
        return out

    def named(points: np.ndarray) -> dict:
        return {n: [round(float(v), 3) for v in p]
                for n, p in zip(HAND21_NAMES, points, strict=True)}

    out["hand"] = {
        "scale": fit.scale, "scale_fitted": fit.scale_fitted,
        "keypoints_world_mm": named(real_keypoints(fit.keypoints_world, rig)),
        "keypoints_camera_mm": {cam.name: named(real_keypoints(fit.keypoints_camera(cam), rig))
                                for cam in rig},
        "joint_angles_deg": fit.joint_angles_deg(),
        "state": dict(zip(fit.model.state_names, fit.scaled_state().tolist(), strict=True)),
        "reprojection_rms_px": float(np.sqrt(np.mean(fit.reprojection_px ** 2)))
        if fit.reprojection_px.size else None,
    }
    return out


def write_pose_csv(result: PoseResult, rig: Rig, path: str | Path) -> None:
    """One row per keypoint and camera: pixel position and confidence of the detection,
    the fitted point in that camera's frame (mm)."""
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(["camera", "keypoint", "u_px", "v_px", "confidence", "x_cam_mm",
                         "y_cam_mm", "z_cam_mm"])
        for cam, cand in zip(rig, real_candidates(result, rig), strict=True):
            xyz = (real_keypoints(result.fit.keypoints_camera(cam), rig)
                   if result.fit is not None else np.full((21, 3), np.nan))
            for k, name in enumerate(HAND21_NAMES):
                uv = (np.full(2, np.nan) if cand is None else cand.keypoints[k])
                conf = np.nan if cand is None else cand.keypoint_confidence[k]
                writer.writerow([cam.name, name, f"{uv[0]:.2f}", f"{uv[1]:.2f}", f"{conf:.3f}",
                                 *(f"{v:.2f}" for v in xyz[k])])


def write_pose_json(record: dict, path: str | Path) -> None:
    """Write :func:`pose_to_json`'s record."""
    Path(path).write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")
