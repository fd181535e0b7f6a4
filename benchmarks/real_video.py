"""Real-data benchmark: the real video tracked end to end from an automatic start.

Usage::

    python benchmarks/real_video.py [--data ../shared/data] [--frames N]
                                    [--detector auto|mediapipe|classic] [--json FILE]

Runs :func:`digiteyes.track_job.run_track_job` (what ``digiteyes track VIDEO --init auto``
runs) on ``real_video/human_hand_video.mp4`` (621 frames, 1280x720, a right hand before a
grey wall) with the shipped ``hand`` model, the default camera (60 deg field of view), the
feature tracker and recovery after lost frames, on one core (numba, BLAS and OpenMP limited
to one thread before anything is imported). Figures:

* frames tracked, frames without a state (video frames before the automatic start or never
  reached), frames flagged lost, re-detections;
* frames per second of the whole per-frame loop (decoding, tracking, detection when it
  runs, logs), and of the tracker plus recovery alone;
* agreement with the stored MediaPipe estimate (``mediapipe_joints_right.pkl``, machine
  output in a wrist-centred frame, *not truth*): mean distance of the 21 keypoints after a
  similarity alignment, mm (median and 90th percentile over frames).

Results go to ``benchmarks/results/real_video.json``. Without the data the script says so
and exits with status 0.
"""

from __future__ import annotations

import os

for _name in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_name] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import pickle  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from digiteyes.benchmarks._machine import machine_info  # noqa: E402
from digiteyes.detect.hand21 import model_anchors  # noqa: E402
from digiteyes.io import read_state_log  # noqa: E402
from digiteyes.io.video_lengths import count_frames  # noqa: E402
from digiteyes.kinematics import forward_kinematics, load_model  # noqa: E402
from digiteyes.kinematics.procrustes import kabsch  # noqa: E402
from digiteyes.track_job import AUTO, TrackJob, run_track_job  # noqa: E402

DEFAULT_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
RESULTS = Path(__file__).resolve().parent / "results"
VIDEO = Path("real_video") / "human_hand_video.mp4"
STORED = Path("real_video") / "mediapipe_joints_right.pkl"
TARGET_FPS = 60.0


def hand21_world(model, states: np.ndarray) -> np.ndarray:
    """The 21 keypoints (T, 21, 3), mm, of each state."""
    rows, points = model_anchors(model)
    return np.stack([forward_kinematics(model, q).points(rows, points) for q in states])


def shape_gap_mm(ours: np.ndarray, reference: np.ndarray) -> float:
    """Mean keypoint distance (mm, our scale) after aligning ``reference`` to ``ours`` by
    rotation, translation and scale."""
    R, t, c = kabsch(reference, ours)
    return float(np.linalg.norm(c * reference @ R.T + t - ours, axis=1).mean())


def measure(data: Path, frames: int | None, detector: str, out_dir: Path) -> dict:
    machine = machine_info()
    video = data / VIDEO
    job = TrackJob((str(video),), str(out_dir), "hand", init_path=AUTO, max_frames=frames,
                   overlay=False, progress=False, detector=detector)
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
    return {
        "benchmark": "real_video", "machine": machine, "video": str(VIDEO),
        "detector": summary["start"]["detector"], "camera": "default, 60 deg horizontal",
        "frames_limit": frames, "video_frames": video_frames, "frames_tracked": run.n_frames,
        "first_frame": start, "frames_without_state": video_frames - run.n_frames,
        "lost_frames": run.n_lost, "re_detections": len(run.reinitialised_frames),
        "re_detected_frames": [start + f for f in run.reinitialised_frames],
        "detection_seconds": summary["start"]["detection_seconds"],
        "loop_fps": run.loop_fps, "tracker_and_recovery_fps": run.tracker_fps,
        "target_fps": TARGET_FPS,
        "shape_gap_to_stored_mediapipe_mm": {
            "median": float(np.median(gaps)) if gaps else None,
            "p90": float(np.percentile(gaps, 90)) if gaps else None, "frames": len(gaps)},
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--frames", type=int, default=None, help="track only the first N")
    parser.add_argument("--detector", default="auto", choices=("auto", "mediapipe", "classic"))
    parser.add_argument("--json", type=Path, default=RESULTS / "real_video.json")
    args = parser.parse_args(argv)
    if not (args.data / VIDEO).is_file() or not (args.data / STORED).is_file():
        print(f"real_video: no {VIDEO} or {STORED} under {args.data}; skipped")
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        result = measure(args.data, args.frames, args.detector, Path(tmp) / "track")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    gap = result["shape_gap_to_stored_mediapipe_mm"]
    print(f"real video: {result['frames_tracked']}/{result['video_frames']} frames tracked "
          f"from frame {result['first_frame']} ({result['detector']}), "
          f"{result['frames_without_state']} without a state, {result['lost_frames']} lost, "
          f"{result['re_detections']} re-detections; {result['loop_fps']:.1f} frames/s "
          f"end to end (target {TARGET_FPS:g}); shape gap to stored MediaPipe median "
          f"{gap['median']} mm -> {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
