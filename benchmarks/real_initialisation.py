"""Real-data benchmark of initialisation: detectors and the model fit on real images.

Usage::

    python benchmarks/real_initialisation.py [--data ../shared/data] [--json FILE]
                                             [--video-step N] [--picture PNG]

1. **STB** (left image of the B1Counting BB pair, 3D labels, known camera): classic and
   MediaPipe detections each fitted by the model (one camera, nominal hand size and the
   size fitted to the labels); root-relative 3D joint error (mm, root = middle MCP, the 20
   finger and thumb joints STB shares with the 21 keypoints), metric error of the root
   position (mm) and 2D keypoint error (px); for MediaPipe also the root-relative error of
   its own 3D keypoints (world landmarks) in the same run, the figure to beat, and our
   fit with those 3D keypoints as a shape term too
   (:class:`~digiteyes.detect.model_fit.KeypointObservation` ``shape_3d``, an option
   that is off by default). STB shows a
   left hand: the image is flipped and the world mirrored (as in ``real_stb.py``) so the
   right-hand model applies. Also the time of ``digiteyes pose`` on this 640x480 image
   (:func:`digiteyes.detect.pose.estimate_pose`: detection and fit; median of
   :data:`POSE_REPEATS`, after one untimed call).
2. **FreiHAND** (8 annotated 224x224 images, 2D labels): 2D keypoint error (px) and
   detection rate of both detectors.
2b. **Link lengths on STB** (both images of the pair, the calibrated stereo rig): each
   detector's keypoints in the two views triangulated
   (:func:`digiteyes.detect.link_lengths.triangulate`) and the 15 finger segments
   measured, against the same segments of the 3D labels (mm); and both views fitted
   together with the hand's scale free, as ``pose LEFT RIGHT --rig`` fits them
   (root-relative and root errors), beside each MediaPipe view's own 3D keypoints.
2c. **InterHand2.6M** (4 annotated 334x512 images with 3D joints and their cameras):
   for each annotated hand (three right, three left; a left hand through the mirror image,
   as ``--hand left`` runs it), each detector's candidate nearest the hand's projected
   joints (oracle association: three of the images show two hands) among those it does
   not name the other side (:mod:`digiteyes.detect.side`, as ``pose --hand`` takes them;
   until 27 Nov, ninth session, a detection of the other hand counted too),
   its 2D error, the one-camera fit's root-relative and root errors (default hand size),
   and MediaPipe's own 3D keypoints' root-relative error in the same run.
3. **The real video** (621 frames, 1280x720, grey wall): detection rate per frame of both
   detectors, time per frame (classic detection + fit), and agreement of the fitted 3D
   hand shape with the stored MediaPipe estimate (``mediapipe_joints_right.pkl``, not
   truth): mean joint distance after a similarity alignment (Procrustes), mm.

Without the data the script says so and exits with status 0.
"""

from __future__ import annotations

import argparse
import json
import pickle
import sys
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from real_stb import load_stb, mirror, stb_rig

from digiteyes import load_model
from digiteyes.benchmarks._machine import machine_info
from digiteyes.camera import Camera, Rig
from digiteyes.camera.default import default_camera
from digiteyes.camera.mirror import mirror_images, mirrored_camera, unmirror_points
from digiteyes.detect.hand21 import BONES
from digiteyes.detect.hand_size import measure_hand
from digiteyes.detect.link_lengths import (
    SEGMENT_NAMES,
    segment_lengths,
    triangulate,
    with_link_lengths,
)
from digiteyes.detect.mediapipe_detector import mediapipe_available
from digiteyes.detect.model_fit import FitOptions, KeypointObservation, fit_keypoints
from digiteyes.detect.pose import estimate_pose, make_detector
from digiteyes.detect.side import is_other_hand
from digiteyes.errors import DigitEyesError
from digiteyes.io.video import VideoReader
from digiteyes.kinematics.procrustes import kabsch
from digiteyes.kinematics.scaling import scaled_model

DEFAULT_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
RESULTS = Path(__file__).resolve().parent / "results"
# STB index of each of the 21 keypoints (STB has the palm centre, not the wrist: -1)
STB_OF_HAND21 = [-1, 17, 18, 19, 20, 13, 14, 15, 16, 9, 10, 11, 12, 5, 6, 7, 8, 1, 2, 3, 4]
ROOT = 9  # middle MCP
POSE_REPEATS = 15


def root_errors(points: np.ndarray, truth: np.ndarray) -> dict:
    """Root-relative error (mean over the 20 finger and thumb keypoints, root = the middle
    MCP) and the root's position error, mm, of keypoints (21, 3) against the truth."""
    rel = (points[1:] - points[ROOT]) - (truth[1:] - truth[ROOT])
    return {"root_relative_mm": float(np.linalg.norm(rel, axis=1).mean()),
            "root_position_mm": float(np.linalg.norm(points[ROOT] - truth[ROOT]))}


SHAPE_SIGMA_MM = 15.0
"""``FitOptions.sigma_shape_mm`` of the extra fit that also uses a detector's 3D shape."""
NAMES = ("classic", "mediapipe", "mediapipe-lite")
"""The detectors compared (:func:`digiteyes.detect.pose.make_detector`'s names), in table
order; the MediaPipe ones when the extra is installed."""


def detectors(video: bool = False) -> dict:
    """The detectors of :data:`NAMES`; on single images asked for two hands, as ``pose``
    asks, so that the hand of the annotated side can be told from the other one."""
    return {name: make_detector(name, video=video, max_hands=1 if video else 2)
            for name in NAMES if name == "classic" or mediapipe_available()}


def stb_stage(data: Path, hand) -> dict | None:
    stb = load_stb(data)
    if stb is None:
        return None
    height, width = stb["images"][0].shape[:2]
    cam = stb_rig(stb["camera"], width, height, mirrored=True)[0]
    image = np.ascontiguousarray(stb["images"][0][:, ::-1])
    truth = mirror(stb["joints"][0])
    common = [k for k in range(21) if STB_OF_HAND21[k] >= 0]
    truth21 = np.full((21, 3), np.nan)
    truth21[common] = truth[[STB_OF_HAND21[k] for k in common]]
    truth_px = cam.project(truth21[common])
    # the hand size fitted to the labels (3D fit): what "the hand's size known" means
    size = fit_keypoints(hand, target_3d=truth21, options=FitOptions(
        fit_scale=True)).scale
    out = {"image": "B1Counting BB_left_0 (flipped)", "labelled_scale": size}
    for name, det in detectors().items():
        start = time.perf_counter()
        cand = det.detect(image, cam)
        seconds = time.perf_counter() - start
        if not cand:
            out[name] = {"detected": False}
            continue
        c = cand[0]
        row = {"detected": True, "detect_ms": 1000 * seconds,
               "px_error_mean": float(np.linalg.norm(c.keypoints[common] - truth_px,
                                                     axis=1).mean())}
        for label, scale in (("default size", 1.0), ("known size", size)):
            fit = fit_keypoints(hand, [KeypointObservation.of(c, cam)],
                                options=FitOptions(scale=scale))
            p = fit.keypoints_world
            row[label] = root_errors(p, truth21)
        if c.keypoints_3d is not None:  # the same fit with the detector's 3D shape too
            p = fit_keypoints(hand, [KeypointObservation.of(c, cam)],
                              options=FitOptions(sigma_shape_mm=SHAPE_SIGMA_MM)).keypoints_world
            row["default size, with its 3D shape"] = root_errors(p, truth21)
        if c.keypoints_3d is not None:  # the detector's own metric 3D (MediaPipe's world)
            row["own_3d_root_relative_mm"] = root_errors(c.keypoints_3d,
                                                         truth21)["root_relative_mm"]
        timings = [estimate_pose([image], Rig((cam,)), det, hand).seconds
                   for _ in range(POSE_REPEATS + 1)][1:]
        row["pose_ms_median"] = {key: 1000 * float(np.median([t[key] for t in timings]))
                                 for key in ("detect", "fit")}
        row["pose_ms_median"]["total"] = 1000 * float(np.median(
            [t["detect"] + t["fit"] for t in timings]))
        out[name] = row
    return out


def freihand_stage(data: Path) -> dict | None:
    root = data / "annotated_images" / "tests" / "data" / "freihand"
    if not (root / "test_freihand.json").is_file():
        return None
    meta = json.loads((root / "test_freihand.json").read_text())
    files = {im["id"]: im["file_name"] for im in meta["images"]}
    out = {}
    for name, det in detectors().items():
        errors, found = [], 0
        for ann in meta["annotations"]:
            rgb = cv2.cvtColor(cv2.imread(str(root / files[ann["image_id"]])), cv2.COLOR_BGR2RGB)
            truth = np.array(ann["keypoints"], dtype=float).reshape(21, 3)[:, :2]
            cand = det.detect(rgb)
            if cand:
                found += 1
                errors.append(float(np.linalg.norm(cand[0].keypoints - truth, axis=1).mean()))
        out[name] = {"images": len(meta["annotations"]), "detected": found,
                     "px_error_mean": float(np.mean(errors)) if errors else None}
    return out


def shape_gap_mm(ours: np.ndarray, reference: np.ndarray) -> float:
    """Mean joint distance (mm, in our scale) after aligning ``reference`` to ``ours`` by
    rotation, translation and scale."""
    R, t, c = kabsch(reference, ours)
    return float(np.linalg.norm(c * reference @ R.T + t - ours, axis=1).mean())


def video_stage(data: Path, hand, step: int) -> dict | None:
    folder = data / "real_video"
    if not (folder / "human_hand_video.mp4").is_file():
        return None
    stored = np.asarray(pickle.loads((folder / "mediapipe_joints_right.pkl").read_bytes()))
    dets = detectors(video=True)  # landmarks followed from frame to frame
    counts = dict.fromkeys(dets, 0)
    gaps = {n: [] for n in dets}
    classic_ms = []
    px_gap, tip_gap = [], []  # classic keypoints against MediaPipe's of the same frame
    frames = 0
    cam = None
    with VideoReader(folder / "human_hand_video.mp4") as reader:
        for index, rgb in enumerate(reader):
            if index % step:
                continue
            frames += 1
            if cam is None:
                cam = default_camera(rgb.shape[1], rgb.shape[0])
            found = {}
            for name, det in dets.items():
                start = time.perf_counter()
                cand = det.detect(rgb, cam)
                if not cand:
                    continue
                found[name] = cand[0].keypoints
                counts[name] += 1
                c = cand[0]
                fit = fit_keypoints(hand, [KeypointObservation.of(c, cam)])
                if name == "classic":
                    classic_ms.append(1000 * (time.perf_counter() - start))
                if index < len(stored) and np.abs(stored[index]).sum() > 0:
                    gaps[name].append(shape_gap_mm(fit.keypoints_world, stored[index]))
            if "classic" in found and "mediapipe" in found:
                d = np.linalg.norm(found["classic"] - found["mediapipe"], axis=1)
                px_gap.append(float(np.median(d)))
                tip_gap.append(float(np.median(d[[4, 8, 12, 16, 20]])))
    return {"frames": frames, "step": step, "camera": "default, 60 deg horizontal field",
            **{name: {"detection_rate": counts[name] / frames,
                      "shape_gap_to_stored_mediapipe_mm_median":
                          float(np.median(gaps[name])) if gaps[name] else None}
               for name in dets},
            "classic_detect_and_fit_ms_median": float(np.median(classic_ms))
            if classic_ms else None,
            "classic_vs_mediapipe_px_median": float(np.median(px_gap)) if px_gap else None,
            "classic_vs_mediapipe_tips_px_median": float(np.median(tip_gap)) if tip_gap
            else None,
            "classic_tips_within_30px_of_mediapipe": float(np.mean(np.array(tip_gap) < 30))
            if tip_gap else None}


INTERHAND = Path("annotated_images") / "tests" / "data" / "interhand2.6m"
INTERHAND_OF_HAND21 = [20, 3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12, 19, 18, 17, 16]
"""InterHand joint (tip first per digit, wrist last) of each of the 21 keypoints."""


def interhand_stage(data: Path, hand) -> dict | None:
    """The InterHand2.6M test images (see the module docstring), every annotated hand: a
    left hand through the mirror image (flipped image, mirrored camera and truth,
    :mod:`digiteyes.camera.mirror`), as ``--hand left`` runs it."""
    root = data / INTERHAND
    if not (root / "test_interhand2.6m_data.json").is_file():
        return None
    cameras, joints, meta = (json.loads((root / f"test_interhand2.6m_{name}.json").read_text())
                             for name in ("camera", "joint_3d", "data"))
    out: dict = {"images": len(meta["images"]), "right_hands": 0, "left_hands": 0}
    rows: dict[str, list[dict]] = {name: [] for name in detectors()}
    for image, ann in zip(meta["images"], meta["annotations"], strict=True):
        valid = np.array(ann["joint_valid"]).ravel()
        capture, cam_id = str(image["capture"]), image["camera"]
        params = {k: cameras[capture][k][cam_id] for k in ("campos", "camrot", "focal",
                                                           "princpt")}
        world = np.array(joints[capture][str(image["frame_idx"])]["world_coord"])
        (fx, fy), (cx, cy) = params["focal"], params["princpt"]
        real_camera = Camera.create(cam_id, np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1]]),
                                    image["width"], image["height"], np.eye(4))
        rgb = cv2.cvtColor(cv2.imread(str(root / image["file_name"])), cv2.COLOR_BGR2RGB)
        for side, joint_rows in (("right", slice(0, 21)), ("left", slice(21, 42))):
            if not valid[joint_rows].all():
                continue
            out[f"{side}_hands"] += 1
            truth = (world[joint_rows][INTERHAND_OF_HAND21] - params["campos"]) \
                @ np.array(params["camrot"]).T
            camera = real_camera if side == "right" else mirrored_camera(real_camera)
            view = rgb if side == "right" else mirror_images([rgb])[0]
            if side == "left":
                truth = unmirror_points(truth)  # the mirror image's right hand
            truth_px = camera.project(truth)
            label = f"{image['file_name']} ({side})"
            for name, det in detectors().items():
                # the annotated hand is a right one in ``view``: a detection the detector
                # names the other side is the other hand (digiteyes.detect.side)
                found = [c for c in det.detect(view, camera) if not is_other_hand(c)]
                if not found:
                    rows[name].append({"image": label, "side": side, "detected": False})
                    continue
                c = min(found,
                        key=lambda k: np.linalg.norm(k.keypoints - truth_px, axis=1).mean())
                p = fit_keypoints(hand, [KeypointObservation.of(c, camera)]).keypoints_world
                row = {"image": label, "side": side, "detected": True,
                       "px_error_mean": float(np.linalg.norm(c.keypoints - truth_px,
                                                             axis=1).mean()),
                       **root_errors(p, truth)}
                if c.keypoints_3d is not None:  # the same fit with the detector's 3D shape
                    p2 = fit_keypoints(hand, [KeypointObservation.of(c, camera)],
                                       options=FitOptions(sigma_shape_mm=SHAPE_SIGMA_MM)
                                       ).keypoints_world
                    row["with_its_3d_shape"] = root_errors(p2, truth)
                    row["own_3d_root_relative_mm"] = root_errors(c.keypoints_3d,
                                                                 truth)["root_relative_mm"]
                rows[name].append(row)
    out["detectors"] = rows
    out["means"] = {name: _interhand_means(r) for name, r in rows.items()}
    return out


def _interhand_means(rows: list[dict]) -> dict:
    """Detected hands and the mean figures over them (ours and, where given, the detector's
    own 3D keypoints on the same hands)."""
    found = [r for r in rows if r["detected"]]
    means: dict = {"hands": len(rows), "detected": len(found)}
    if found:
        means["root_relative_mm"] = float(np.mean([r["root_relative_mm"] for r in found]))
        means["root_position_mm"] = float(np.mean([r["root_position_mm"] for r in found]))
        own = [r["own_3d_root_relative_mm"] for r in found if "own_3d_root_relative_mm" in r]
        if len(own) == len(found):
            means["own_3d_root_relative_mm"] = float(np.mean(own))
    return means


def stb_link_length_stage(data: Path, hand) -> dict | None:
    """Segment lengths triangulated from each detector's keypoints in both STB views,
    against the labels' (the flipped images and the mirrored rig, as :func:`stb_stage`);
    then the one-camera fit of the left view with the hand measured this way, as
    ``calibrate-hand --rig`` measures it (``calibrated``: the stereo-fitted scale;
    ``personal``: that scale and the 15 segments), root-relative and root errors (mm).
    The same pair serves to measure the hand and to test it: the sample has one pair."""
    stb = load_stb(data)
    if stb is None:
        return None
    height, width = stb["images"][0].shape[:2]
    rig = stb_rig(stb["camera"], width, height, mirrored=True)
    images = [np.ascontiguousarray(image[:, ::-1]) for image in stb["images"]]
    truth = mirror(stb["joints"][0])
    truth21 = np.full((21, 3), np.nan)
    truth21[1:] = truth[STB_OF_HAND21[1:]]
    labelled = segment_lengths(truth21)
    out: dict = {"segments": list(SEGMENT_NAMES), "labelled_mm": labelled.tolist()}
    for name, det in detectors().items():
        found = [det.detect(image, cam) for image, cam in zip(images, rig, strict=True)]
        if not all(found):
            out[name] = {"detected_in_both": False}
            continue
        measured = segment_lengths(triangulate(rig, [f[0].keypoints for f in found]))
        error = measured - labelled
        out[name] = {"detected_in_both": True, "measured_mm": measured.tolist(),
                     "abs_error_mm_mean": float(np.abs(error).mean()),
                     "abs_error_mm_max": float(np.abs(error).max()),
                     "relative_error_mean": float(np.abs(error / labelled).mean())}
        measured_hand = measure_hand([images], rig, det, hand)  # as calibrate-hand does
        scale = measured_hand.scale
        variants = [("calibrated", hand, scale)]
        if measured_hand.lengths is not None:
            variants.append(("personal", with_link_lengths(scaled_model(hand, scale),
                                                           measured_hand.lengths), 1.0))
        # both views fitted together, as `pose LEFT RIGHT --rig` fits them
        # (estimate_pose's fit of the detections above)
        try:
            both = fit_keypoints(hand, [KeypointObservation.of(f[0], cam)
                                        for f, cam in zip(found, rig, strict=True)],
                                 options=FitOptions())
            out[name]["both_views"] = {"scale": both.scale,
                                       **root_errors(both.keypoints_world, truth21)}
        except DigitEyesError:  # detections no pose of the hand explains
            pass
        own = [f[0].keypoints_3d for f in found]
        if all(k is not None for k in own):  # the views share the left camera's axes
            out[name]["own_3d_root_relative_mm_per_view"] = [
                root_errors(k, truth21)["root_relative_mm"] for k in own]
        left = [KeypointObservation.of(found[0][0], rig[0])]
        for label, model, s in variants:
            p = fit_keypoints(model, left, options=FitOptions(scale=s)).keypoints_world
            out[name][label] = {"scale": scale, **root_errors(p, truth21)}
    return out


def format_table(result: dict) -> str:
    m = result["machine"]
    lines = [f"Initialisation on real data ({result['data']})",
             f"machine: {m['cpu']}, {m['cores']} cores ({m.get('cores_usable')} usable), python "
             f"{m['python']}, numpy "
             f"{m['numpy']}, load average (1 min) {m.get('load_average_start')} at the start"]
    stb = result.get("stb")
    if stb:
        lines += ["", f"STB {stb['image']}: labelled hand scale {stb['labelled_scale']:.3f}",
                  f"  {'detector':<14} {'2D px':>6} {'rel mm (def)':>13} {'root mm (def)':>14}"
                  f" {'rel mm (known)':>15} {'root mm (known)':>16}"]
        for name in NAMES:
            r = stb.get(name)
            if not r:
                continue
            if not r["detected"]:
                lines.append(f"  {name:<14} not detected")
                continue
            d, k = r["default size"], r["known size"]
            lines.append(f"  {name:<14} {r['px_error_mean']:6.1f} {d['root_relative_mm']:13.1f}"
                         f" {d['root_position_mm']:14.1f} {k['root_relative_mm']:15.1f}"
                         f" {k['root_position_mm']:16.1f}")
            if "own_3d_root_relative_mm" in r:
                lines.append(f"  {name:<14} its own 3D keypoints (world landmarks): root-relative"
                             f" {r['own_3d_root_relative_mm']:.1f} mm")
                shaped = r["default size, with its 3D shape"]
                lines.append(f"  {name:<14} our fit with its 3D shape too (sigma "
                             f"{SHAPE_SIGMA_MM:g} mm), default size: root-relative "
                             f"{shaped['root_relative_mm']:.1f} mm, root "
                             f"{shaped['root_position_mm']:.1f} mm")
    if stb:
        for name in NAMES:
            r = stb.get(name) or {}
            if "pose_ms_median" in r:
                t = r["pose_ms_median"]
                lines.append(f"  pose on the 640x480 image, {name}: {t['total']:.0f} ms "
                             f"(detection {t['detect']:.0f}, fit {t['fit']:.0f}; median)")
    lengths = result.get("stb_link_lengths")
    if lengths:
        lines += ["", "STB finger segments triangulated from both views (labels: "
                  f"{np.mean(lengths['labelled_mm']):.1f} mm mean segment)"]
        for name in NAMES:
            r = lengths.get(name)
            if not r:
                continue
            if not r["detected_in_both"]:
                lines.append(f"  {name:<14} not detected in both views")
                continue
            lines.append(f"  {name:<14} mean |error| {r['abs_error_mm_mean']:.1f} mm "
                         f"({100 * r['relative_error_mean']:.0f} %), worst "
                         f"{r['abs_error_mm_max']:.1f} mm")
            if "both_views" in r:
                b = r["both_views"]
                lines.append(f"  {name:<14} both views fitted together, scale free (`pose "
                             f"LEFT RIGHT --rig`; scale {b['scale']:.3f}): root-relative "
                             f"{b['root_relative_mm']:.1f} mm, root {b['root_position_mm']:.1f} mm")
            if "own_3d_root_relative_mm_per_view" in r:
                lines.append(f"  {name:<14} its own 3D keypoints, left and right view: "
                             "root-relative " + " and ".join(
                                 f"{v:.1f}" for v in r["own_3d_root_relative_mm_per_view"])
                             + " mm")
            for label in ("calibrated", "personal"):
                if label not in r:
                    continue
                c = r[label]
                lines.append(f"  {name:<14} left view alone, hand {label} from the pair "
                             f"(scale {c['scale']:.3f}): root-relative "
                             f"{c['root_relative_mm']:.1f} mm, root {c['root_position_mm']:.1f} mm")
    ih = result.get("interhand")
    if ih:
        lines += ["", f"InterHand2.6M: {ih['right_hands']} right and {ih['left_hands']} left "
                  f"hands annotated in {ih['images']} images (3D, camera known; default hand "
                  "size; left hands through the mirror image)"]
        for name, m in ih["means"].items():
            if m["detected"]:
                own = m.get("own_3d_root_relative_mm")
                lines.append(f"  {name:<14} mean over {m['detected']} of {m['hands']} hands "
                             f"found: root-relative {m['root_relative_mm']:.1f} mm, root "
                             f"{m['root_position_mm']:.1f} mm"
                             + ("" if own is None else f"; its own 3D {own:.1f} mm"))
        for name, rows in ih["detectors"].items():
            for r in rows:
                if not r["detected"]:
                    lines.append(f"  {name:<14} {r['image']}: not detected")
                    continue
                own = r.get("own_3d_root_relative_mm")
                lines.append(f"  {name:<14} {r['image']}: 2D {r['px_error_mean']:.1f} px, "
                             f"root-relative {r['root_relative_mm']:.1f} mm, root "
                             f"{r['root_position_mm']:.1f} mm"
                             + ("" if own is None else
                                f"; its own 3D {own:.1f} mm; our fit with its 3D shape "
                                f"too: {r['with_its_3d_shape']['root_relative_mm']:.1f} / "
                                f"{r['with_its_3d_shape']['root_position_mm']:.1f} mm"))
    fh = result.get("freihand")
    if fh:
        lines += ["", "FreiHAND (2D labels)"]
        for name, r in fh.items():
            err = "-" if r["px_error_mean"] is None else f"{r['px_error_mean']:.1f} px"
            lines.append(f"  {name:<14} detected {r['detected']}/{r['images']}, mean 2D error "
                         f"{err}")
    video = result.get("video")
    if video:
        lines += ["", f"real video: {video['frames']} frames (every {video['step']}), "
                  f"{video['camera']}"]
        for name in NAMES:
            if name in video:
                gap = video[name]["shape_gap_to_stored_mediapipe_mm_median"]
                rate = 100 * video[name]["detection_rate"]
                lines.append(f"  {name:<14} detection rate {rate:.0f}"
                             f" %, shape gap to stored MediaPipe "
                             f"{'-' if gap is None else f'{gap:.1f} mm'} (median)")
        if video["classic_vs_mediapipe_px_median"] is not None:
            lines.append(f"  classic vs MediaPipe (same frames): keypoints "
                         f"{video['classic_vs_mediapipe_px_median']:.0f} px, tips "
                         f"{video['classic_vs_mediapipe_tips_px_median']:.0f} px (medians); "
                         f"tips within 30 px in "
                         f"{100 * video['classic_tips_within_30px_of_mediapipe']:.0f} % of frames")
        if video["classic_detect_and_fit_ms_median"] is not None:
            lines.append(f"  classic detection + fit: "
                         f"{video['classic_detect_and_fit_ms_median']:.0f} ms per 1280x720 frame"
                         " (median)")
    return "\n".join(lines)


def draw_hand(image: np.ndarray, points: np.ndarray, colour: tuple[int, int, int],
              radius: int = 4) -> None:
    """Draw 21 keypoints (px) and their bones on an RGB image, in place."""
    for a, b in BONES:
        cv2.line(image, tuple(np.round(points[a]).astype(int)),
                 tuple(np.round(points[b]).astype(int)), colour, 2, cv2.LINE_AA)
    for p in points:
        cv2.circle(image, tuple(np.round(p).astype(int)), radius, colour, -1, cv2.LINE_AA)


def write_picture(data: Path, path: Path, frame_index: int = 0) -> None:
    """Detections and fits on one frame of the real video: classic detector (mask in
    blue, keypoints in yellow, the fitted model's keypoints in magenta) and MediaPipe."""
    hand = load_model("hand")
    with VideoReader(data / "real_video" / "human_hand_video.mp4") as reader:
        rgb = reader.read()
        for _ in range(frame_index):
            rgb = reader.read()
    cam = default_camera(rgb.shape[1], rgb.shape[0])
    panels = []
    for name, det in detectors().items():
        canvas = rgb.copy()
        cand = det.detect(rgb, cam)[0]
        if cand.mask is not None:
            canvas[cand.mask] = (0.6 * canvas[cand.mask] + (0, 0, 100)).astype(np.uint8)
        fit = fit_keypoints(hand, [KeypointObservation.of(cand, cam)])
        draw_hand(canvas, cand.keypoints, (255, 220, 0))
        draw_hand(canvas, cam.project(fit.keypoints_world), (255, 0, 255), 3)
        x0, y0, x1, y1 = (int(v) for v in cand.bbox)
        crop = canvas[max(y0 - 60, 0):y1 + 120, max(x0 - 60, 0):x1 + 60]
        crop = cv2.resize(crop, (360, round(360 * crop.shape[0] / crop.shape[1])))
        depth = cam.to_camera(fit.keypoints_world)[ROOT, 2]
        cv2.putText(crop, f"{name}: fit at {depth:.0f} mm", (8, 22), cv2.FONT_HERSHEY_SIMPLEX,
                    0.6, (255, 255, 255), 2, cv2.LINE_AA)
        panels.append(crop)
    height = min(p.shape[0] for p in panels)
    path.parent.mkdir(parents=True, exist_ok=True)
    from PIL import Image

    Image.fromarray(np.hstack([p[:height] for p in panels])).quantize(128).save(path,
                                                                             optimize=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--json", type=Path, default=RESULTS / "real_initialisation.json")
    parser.add_argument("--video-step", type=int, default=3, help="use every N-th video frame")
    parser.add_argument("--only", choices=("stb", "interhand"),
                        help="rerun only these stages into the existing JSON")
    parser.add_argument("--picture", type=Path,
                        help="only write the picture of a detection and fit on video frame 0")
    args = parser.parse_args(argv)
    if not args.data.is_dir():
        print(f"no real data under {args.data}: nothing to measure")
        return 0
    if args.picture is not None:
        write_picture(args.data, args.picture)
        print(f"wrote {args.picture}")
        return 0
    hand = load_model("hand")
    if args.only and args.json.is_file():
        result = json.loads(args.json.read_text())
    else:
        result = {"data": str(args.data), "machine": machine_info(),
                  "mediapipe": mediapipe_available(),
                  "freihand": freihand_stage(args.data),
                  "video": video_stage(args.data, hand, args.video_step)}
    if args.only in (None, "stb"):
        result["stb"] = stb_stage(args.data, hand)
        result["stb_link_lengths"] = stb_link_length_stage(args.data, hand)
    if args.only in (None, "interhand"):
        result["interhand"] = interhand_stage(args.data, hand)
    table = format_table(result)
    print(table)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(result, indent=1) + "\n")
    args.json.with_suffix(".txt").write_text(table + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
