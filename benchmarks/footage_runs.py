"""What the real-footage benchmarks share: frames read, MediaPipe's reference keypoints,
a video written, tracked as ``digiteyes track VIDEO`` runs it, and scored against the
reference (``real_two_hands.py``, ``real_video_degraded.py``).

The score of a run: per frame with a reference, the worst digit's mean keypoint distance
between the track and the reference, in palm lengths (:func:`real_video.image_gaps`); a
frame is on the hand when it is under half a palm length. The reference is MediaPipe's
output, not truth.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
from real_video import DEFAULT_DATA, RESULTS, VIDEO, image_gaps

from digiteyes.camera.default import DEFAULT_HFOV_DEG, default_camera
from digiteyes.camera.mirror import mirrored_camera, unmirror_pixels
from digiteyes.detect.mediapipe_detector import MediaPipeDetector, mediapipe_available
from digiteyes.io import StateLog, VideoReader, read_state_log
from digiteyes.io.video import VideoWriter
from digiteyes.kinematics import load_model
from digiteyes.track_job import AUTO, TrackJob, run_track_job

ON_THE_HAND = 0.5
"""A frame is on the hand when its worst digit is within this many palm lengths."""


def footage_parser(description: str, name: str) -> argparse.ArgumentParser:
    """The options every footage benchmark takes: ``--data``, ``--frames`` and ``--json``
    (default ``results/NAME.json``)."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--frames", type=int, default=None, help="only the first N frames")
    parser.add_argument("--json", type=Path, default=RESULTS / f"{name}.json")
    return parser


def can_run(data: Path, name: str) -> bool:
    """Whether the real video and the MediaPipe extra are there; says so when not."""
    if (data / VIDEO).is_file() and mediapipe_available():
        return True
    print(f"{name}: needs {VIDEO} under {data} and the mediapipe extra; skipped")
    return False


def keypoint_states(video: Path, frames: int) -> StateLog:
    """The keypoint tracker's state log (:class:`~digiteyes.io.StateLog`, the ``hand``
    model) on the first ``frames`` frames of ``video``, started as ``digiteyes track
    VIDEO --init auto --tracker keypoints`` starts (the pictures' states)."""
    with tempfile.TemporaryDirectory() as out:
        run_track_job(TrackJob((str(video),), out, "hand", init_path=AUTO, max_frames=frames,
                               overlay=False, progress=False, tracker_name="keypoints"))
        return read_state_log(Path(out) / "states.csv", load_model("hand"))


def read_frames(video: Path, frames: int | None) -> list[np.ndarray]:
    """The first ``frames`` RGB frames of ``video`` (all with None)."""
    with VideoReader(video) as reader:
        return [image for i, image in enumerate(reader) if frames is None or i < frames]


def single_hand_keypoints(images: list[np.ndarray]) -> np.ndarray:
    """MediaPipe (still-image mode) on each frame: (T, 21, 2) px, NaN where no hand."""
    detector = MediaPipeDetector(max_hands=1, static_image_mode=True)
    out = np.full((len(images), 21, 2), np.nan)
    for i, image in enumerate(images):
        if found := detector.detect(image):
            out[i] = found[0].keypoints
    detector.close()
    return out


def write_video(images: list[np.ndarray], path: Path, fps: float = 30.0) -> Path:
    """``images`` as an H.264 video at ``path``."""
    with VideoWriter(path, fps, codec="h264") as writer:
        for image in images:
            writer.write(image)
    return path


def track_and_score(video: Path, out: Path, reference: np.ndarray,
                    hand: str = "auto") -> dict:
    """Track ``video`` as ``digiteyes track VIDEO --hand HAND`` does (automatic start,
    the keypoint tracker, recovery) into ``out`` and score it against ``reference``
    (T, 21, 2) px of the video's frames (NaN: no reference)."""
    run = run_track_job(TrackJob((str(video),), str(out), "hand", init_path=AUTO,
                                 overlay=False, progress=False, hand=hand,
                                 tracker_name="keypoints"))
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    model = load_model("hand")
    states = read_state_log(out / "states.csv", model).states
    with VideoReader(video) as reader:
        first = reader.read()
    height, width = first.shape[:2]
    camera = default_camera(width, height, DEFAULT_HFOV_DEG)
    found = {i: k for i, k in enumerate(reference) if not np.isnan(k).any()}
    if summary["start"]["hand"] == "left":  # the states pose the mirror image's right hand
        camera = mirrored_camera(camera)
        found = {i: unmirror_pixels(k, width) for i, k in found.items()}
    gaps = image_gaps(model, states, summary["start"]["first_frame"], found, camera)[0]
    return {"size": [width, height], "first_frame": summary["start"]["first_frame"],
            "frames_tracked": run.n_frames, "on_the_hand": float(np.mean(gaps < ON_THE_HAND)),
            "gap_palm_lengths": {"median": float(np.median(gaps)),
                                 "p90": float(np.percentile(gaps, 90)),
                                 "frames": int(gaps.size)},
            "lost_frames": run.n_lost, "re_detections": len(run.reinitialised_frames),
            "tracker_fps": run.tracker_fps, "loop_fps": run.loop_fps}


def score_line(row: dict) -> str:
    """One run's figures in a line."""
    gap = row["gap_palm_lengths"]
    return (f"on the hand in {100 * row['on_the_hand']:.1f} % of {gap['frames']} frames "
            f"(gap median {gap['median']:.2f}, 90th percentile {gap['p90']:.2f} palm "
            f"lengths), {row['lost_frames']} lost, {row['re_detections']} re-detections, "
            f"{row['tracker_fps']:.1f} frames/s (tracker), {row['loop_fps']:.1f} end to end")


def save_result(result: dict, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
