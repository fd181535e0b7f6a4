"""Real-data benchmark: the real video tracked end to end from an automatic start.

Usage::

    python benchmarks/real_video.py [--data ../shared/data] [--frames N]
                                    [--detector auto|mediapipe|classic]
                                    [--trackers features,keypoints] [--json FILE]

Runs :func:`digiteyes.track_job.run_track_job` (what ``digiteyes track VIDEO --init auto
--tracker NAME`` runs) on ``real_video/human_hand_video.mp4`` (621 frames, 1280x720, a
right hand before a grey wall) with the shipped ``hand`` model, the default camera (60 deg
field of view) and recovery after lost frames, once per tracker of :data:`TRACKERS` (the
DigitEyes feature tracker, the keypoint tracker and the two joined), on one core (numba,
BLAS and OpenMP limited to one thread before anything is imported). Figures per tracker:

* frames tracked, frames without a state (video frames before the automatic start or never
  reached), frames flagged lost, re-detections;
* frames per second of the whole per-frame loop (decoding, tracking, detection when it
  runs, logs), and of the tracker plus recovery alone;
* agreement with the stored MediaPipe estimate (``mediapipe_joints_right.pkl``, machine
  output in a wrist-centred frame, *not truth*): mean distance of the 21 keypoints after a
  similarity alignment, mm (median and 90th percentile over frames);
* the image gap: on every :data:`IMAGE_STEP`-th frame from frame 1 (not the frames the
  detection check looks at), MediaPipe run on the frame alone
  (still-image mode, after the timed runs) and the tracked hand projected; per frame the
  worst digit's mean keypoint distance in palm lengths (wrist to middle MCP). MediaPipe is
  not truth, and the keypoint tracker follows the same network (in video mode), so its
  gap is small by construction; for the feature tracker, which sees MediaPipe only in its
  checks (every third frame, ``track --check-every``) and re-detections, the gap says
  whether the track stays on the hand between them. A re-detection puts the track on
  MediaPipe's hand, so a run that re-detects more often has a smaller median gap for that
  alone; the gap is therefore also reported on the frames at least :data:`SETTLED_FRAMES`
  after the start or the last re-detection (``settled``), which compares how well two
  runs track rather than how often they re-detect.
* the loss flag's silence: of the frames whose image gap exceeds half a palm length (the
  logged hand off MediaPipe's; ``above_half``), how many the run did not flag lost
  (``above_half_not_flagged``): a hand placed wrong and not said to be.

Results go to ``benchmarks/results/real_video.json``. Without the data the script says so
and exits with status 0.
"""

from __future__ import annotations

import one_thread  # noqa: F401  (first: one thread for the libraries imported below)

# isort: split
import argparse
import json
import pickle
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np

from digiteyes.benchmarks._machine import machine_info
from digiteyes.camera.default import DEFAULT_HFOV_DEG, default_camera
from digiteyes.detect.check import worst_digit_gap
from digiteyes.detect.hand21 import BONES, model_anchors
from digiteyes.detect.mediapipe_detector import (
    MediaPipeDetector,
    mediapipe_available,
)
from digiteyes.io import VideoReader, read_state_log
from digiteyes.io.video_lengths import count_frames
from digiteyes.kinematics import forward_kinematics, load_model
from digiteyes.kinematics.procrustes import kabsch
from digiteyes.track_job import (
    AUTO,
    DEFAULT_CHECK_EVERY,
    TrackJob,
    run_track_job,
)

DEFAULT_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
RESULTS = Path(__file__).resolve().parent / "results"
VIDEO = Path("real_video") / "human_hand_video.mp4"
STORED = Path("real_video") / "mediapipe_joints_right.pkl"
TARGET_FPS = 60.0
TRACKERS = ("features:0", "features", "keypoints", "features+keypoints", "features@classic",
            "divide-conquer@classic", "keypoints@mediapipe-lite")
"""The runs: the DigitEyes feature tracker without and with the detection check every
third frame (``NAME:N`` sets ``--check-every N``; the default otherwise), the keypoint
tracker, the feature tracker anchored by the keypoints (no detection check: it
detects every frame), the feature tracker as a user without the MediaPipe extra runs
it (``NAME@DETECTOR`` sets ``--detector`` for that run: the classic detector starts and
recovers it, and nothing checks it), the particle filter of Huang et al. the same way
(the model-based search over the basis configurations with no learned parts), and the
keypoint tracker on MediaPipe's lite network (the choice for a slow machine)."""
IMAGE_STEP = 3
"""Every how many frames the image gap is measured (frames 1, 4, 7, ...)."""
SETTLED_FRAMES = 3
"""Frames after the start or a re-detection from which the image gap counts as settled."""
PICTURE_FRAMES = (31, 121, 451)
"""Frames of the picture (``--picture``; none a frame the detection check looks at)."""


def hand21_world(model, states: np.ndarray) -> np.ndarray:
    """The 21 keypoints (T, 21, 3), mm, of each state."""
    rows, points = model_anchors(model)
    return np.stack([forward_kinematics(model, q).points(rows, points) for q in states])


def shape_gap_mm(ours: np.ndarray, reference: np.ndarray) -> float:
    """Mean keypoint distance (mm, our scale) after aligning ``reference`` to ``ours`` by
    rotation, translation and scale."""
    R, t, c = kabsch(reference, ours)
    return float(np.linalg.norm(c * reference @ R.T + t - ours, axis=1).mean())


def image_gaps(model, states: np.ndarray, first: int, detections: dict[int, np.ndarray],
               camera, restarts: Sequence[int] = ()
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per detected frame, the worst digit's mean keypoint distance between the track and
    the detection, in palm lengths (wrist to middle MCP of the detection); the frames
    since the start ``first`` or the last of the re-detected frames ``restarts``; and the
    rows of ``states`` they were measured on."""
    rows, points = model_anchors(model)
    gaps, ages, measured = [], [], []
    for i, q in enumerate(states):
        found = detections.get(first + i)
        if found is None:
            continue
        uv = camera.project(forward_kinematics(model, q).points(rows, points))
        gaps.append(worst_digit_gap(uv, found)[0])
        ages.append(first + i - max([first, *(r for r in restarts if r <= first + i)]))
        measured.append(i)
    return np.asarray(gaps), np.asarray(ages), np.asarray(measured, dtype=int)


def static_detections(video: Path, step: int, frames: int | None) -> dict[int, np.ndarray]:
    """MediaPipe in still-image mode (each frame alone) on frames 1, 1 + ``step``, ...
    (not the frames the detection check of ``track`` looks at, 0, ``step``, ...): the 21
    keypoints (px) of the frames where it finds a hand."""
    out = {}
    detector = MediaPipeDetector(max_hands=1, static_image_mode=True)
    with VideoReader(video) as reader:
        for i, image in enumerate(reader):
            if frames is not None and i >= frames:
                break
            if i % step == 1 and (found := detector.detect(image)):
                out[i] = found[0].keypoints
    detector.close()
    return out


def _label(row: dict) -> str:
    """A run's name in the table and the picture."""
    check = row["detection_check"]
    if row["tracker"] in ("keypoints", "features+keypoints"):  # they detect every frame
        detector = row["run"].partition("@")[2]
        return row["tracker"] + (f", {detector} detector" if detector else "")
    classic = row["detector"] == "ClassicDetector"
    no_mediapipe = ", classic detector (no MediaPipe)" if classic else ""
    return (f"{row['tracker']}, " + (f"check every {check['every']}" if check else "no check")
            + no_mediapipe)


def _unflagged(image: dict) -> str:
    """How many of a run's frames off MediaPipe's hand it did not flag lost."""
    if not image.get("above_half"):
        return ""
    return f" ({image['above_half_not_flagged']} of {image['above_half']} not flagged lost)"


def _settled(settled: dict) -> str:
    """The settled image gap of a run, for the printed line."""
    if not settled["frames"]:
        return ""
    return (f"; {SETTLED_FRAMES}+ frames after a (re)start ({settled['frames']} frames): "
            f"median {settled['median']:.2f}, {100 * settled['share_above_half']:.0f} % "
            f"above 0.5")


def write_picture(video: Path, model, logs: dict, path: Path) -> None:
    """Frames :data:`PICTURE_FRAMES` (columns) with each tracker's hand (rows): the
    model's 21 keypoints joined along the bones, red, and MediaPipe's on the frame alone,
    green."""
    rows, points = model_anchors(model)
    camera = default_camera(1280, 720, DEFAULT_HFOV_DEG)
    detector = MediaPipeDetector(max_hands=1, static_image_mode=True)
    images = {}
    with VideoReader(video) as reader:
        for i, image in enumerate(reader):
            if i in PICTURE_FRAMES:
                images[i] = image
            if i >= max(PICTURE_FRAMES):
                break
    grid = []
    for name, (first, log) in logs.items():
        tiles = []
        for i in PICTURE_FRAMES:
            tile = images[i].copy()
            found = detector.detect(tile)
            tracked = camera.project(forward_kinematics(model, log.states[i - first]).points(
                rows, points))
            for pts, colour in ((found[0].keypoints if found else None, (0, 200, 0)),
                                (tracked, (230, 0, 0))):
                for a, b in () if pts is None else BONES:
                    cv2.line(tile, tuple(np.int32(pts[a])), tuple(np.int32(pts[b])), colour, 3,
                             cv2.LINE_AA)
            tile = tile[40:620, 380:1080]
            cv2.putText(tile, f"{name}, frame {i}", (12, 40), cv2.FONT_HERSHEY_SIMPLEX, 1.0,
                        (0, 0, 0), 2, cv2.LINE_AA)
            tiles.append(cv2.resize(tile, (350, 290), interpolation=cv2.INTER_AREA))
        grid.append(np.hstack(tiles))
    detector.close()
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), cv2.cvtColor(np.vstack(grid), cv2.COLOR_RGB2BGR))


def measure(data: Path, frames: int | None, detector: str, run_name: str,
            out_dir: Path) -> dict:
    """One run on the real video (module docstring); ``run_name`` is a tracker's name,
    with ``:N`` for a check every N frames (0: none) and ``@DETECTOR`` for a detector
    other than ``detector``."""
    video = data / VIDEO
    run_spec, _, run_detector = run_name.partition("@")
    detector = run_detector or detector
    tracker, _, every = run_spec.partition(":")
    job = TrackJob((str(video),), str(out_dir), "hand", init_path=AUTO, max_frames=frames,
                   overlay=False, progress=False, detector=detector, tracker_name=tracker,
                   check_every=int(every) if every else DEFAULT_CHECK_EVERY)
    run = run_track_job(job)
    summary = json.loads((out_dir / "summary.json").read_text(encoding="utf-8"))
    model = load_model("hand")
    log = read_state_log(out_dir / "states.csv", model)
    start = summary["start"]["first_frame"]
    video_frames = count_frames(video) if frames is None else frames
    stored = np.asarray(pickle.loads((data / STORED).read_bytes()), dtype=float)
    ours = hand21_world(model, log.states)
    gaps = [shape_gap_mm(ours[i], stored[start + i]) for i in range(len(log))
            if start + i < len(stored) and np.abs(stored[start + i]).sum() > 0]
    row = {
        "run": run_name, "tracker": tracker, "detector": summary["start"]["detector"],
        "detection_check": summary.get("detection_check"),
        "frames_tracked": run.n_frames, "first_frame": start,
        "frames_without_state": video_frames - run.n_frames,
        "lost_frames": run.n_lost, "re_detections": len(run.reinitialised_frames),
        "re_detected_frames": list(run.reinitialised_frames),
        "detection_seconds": summary["start"]["detection_seconds"],
        "loop_fps": run.loop_fps, "tracker_and_recovery_fps": run.tracker_fps,
        "shape_gap_to_stored_mediapipe_mm": {
            "median": float(np.median(gaps)) if gaps else None,
            "p90": float(np.percentile(gaps, 90)) if gaps else None, "frames": len(gaps)},
    }
    return row


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--frames", type=int, default=None, help="track only the first N")
    parser.add_argument("--detector", default="auto", choices=("auto", "mediapipe", "classic"))
    parser.add_argument("--trackers", default=",".join(TRACKERS),
                        help="comma-separated registered trackers (default: %(default)s)")
    parser.add_argument("--json", type=Path, default=RESULTS / "real_video.json")
    parser.add_argument("--picture", type=Path, default=None,
                        help="also draw each tracker's hand on frames "
                             f"{', '.join(map(str, PICTURE_FRAMES))} into this PNG")
    args = parser.parse_args(argv)
    if not (args.data / VIDEO).is_file() or not (args.data / STORED).is_file():
        print(f"real_video: no {VIDEO} or {STORED} under {args.data}; skipped")
        return 0
    machine = machine_info()
    video_frames = count_frames(args.data / VIDEO) if args.frames is None else args.frames
    model = load_model("hand")
    with tempfile.TemporaryDirectory() as tmp:
        rows = [measure(args.data, args.frames, args.detector, name, Path(tmp) / name)
                for name in args.trackers.split(",")]
        # after the timed runs: MediaPipe on single frames, the image gaps' reference
        detections = (static_detections(args.data / VIDEO, IMAGE_STEP, args.frames)
                      if mediapipe_available() else {})
        for row in rows if detections else ():
            log = read_state_log(Path(tmp) / row["run"] / "states.csv", model)
            image, ages, measured = image_gaps(model, log.states, row["first_frame"],
                                               detections,
                                               default_camera(1280, 720, DEFAULT_HFOV_DEG),
                                               row["re_detected_frames"])
            settled = image[ages >= SETTLED_FRAMES]
            off = image > 0.5
            row["image_gap_palm_lengths"] = {
                "frames": int(image.size), "median": float(np.median(image)),
                "p90": float(np.percentile(image, 90)),
                "share_above_half": float(np.mean(off)),
                "above_half": int(off.sum()),
                "above_half_not_flagged": int(np.sum(~log.lost[measured][off])),
                "settled": {"frames": int(settled.size),
                            "median": float(np.median(settled)) if settled.size else None,
                            "share_above_half": float(np.mean(settled > 0.5))
                            if settled.size else None}}
        if args.picture is not None:
            logs = {_label(row): (row["first_frame"], read_state_log(
                Path(tmp) / row["run"] / "states.csv", model)) for row in rows}
            write_picture(args.data / VIDEO, model, logs, args.picture)
            print(f"wrote {args.picture}")
    result = {"benchmark": "real_video", "machine": machine, "video": str(VIDEO),
              "camera": f"default, {DEFAULT_HFOV_DEG:g} deg horizontal",
              "frames_limit": args.frames, "video_frames": video_frames,
              "target_fps": TARGET_FPS, "image_gap_reference":
                  f"MediaPipe on single frames (still-image mode), every {IMAGE_STEP}th "
                  "frame from frame 1; machine output, not truth", "trackers": rows}
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    for row in rows:
        gap, image = row["shape_gap_to_stored_mediapipe_mm"], row.get("image_gap_palm_lengths")
        print(f"real video, {_label(row)}: {row['frames_tracked']}/{video_frames} frames "
              f"tracked from frame {row['first_frame']} ({row['detector']}), "
              f"{row['frames_without_state']} without a state, {row['lost_frames']} lost, "
              f"{row['re_detections']} re-detections; {row['loop_fps']:.1f} frames/s end to "
              f"end (target {TARGET_FPS:g}); shape gap to stored MediaPipe median "
              f"{gap['median']:.1f} mm"
              + ("" if image is None else
                 f"; image gap to MediaPipe median {image['median']:.2f} palm lengths, "
                 f"{100 * image['share_above_half']:.0f} % of frames above 0.5"
                 + _unflagged(image) + _settled(image["settled"])))
    print(f"-> {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
