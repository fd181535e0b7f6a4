"""Real-data benchmark: the real video made harder; does the track stay on the hand?

Usage::

    python benchmarks/real_video_degraded.py [--data ../shared/data] [--frames N] [--json FILE]

The real video (``real_video/human_hand_video.mp4``, 1280x720) is degraded in the ways
footage from users is (:data:`DEGRADATIONS`): dim and noisy, motion-blurred, small,
crossed by an occluder, compressed hard, fast (every third frame only). Each version is
tracked as ``digiteyes track VIDEO`` runs it (:func:`digiteyes.track_job.run_track_job`:
automatic start, the keypoint tracker, recovery; one core). Per version: the share of
frames whose tracked hand lies on the hand (the worst digit's mean keypoint distance
under half a palm length from MediaPipe's keypoints of the *original* frame, still-image
mode: machine output, not truth), the median and 90th percentile of that distance,
frames flagged lost, re-detections and frames per second.

Without the data or the MediaPipe extra the script says so and exits with status 0.
"""

from __future__ import annotations

import one_thread  # noqa: F401  (first: one thread for the libraries imported below)

# isort: split
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
from footage_runs import (
    can_run,
    footage_parser,
    read_frames,
    save_result,
    score_line,
    single_hand_keypoints,
    track_and_score,
    write_video,
)
from real_video import VIDEO

from digiteyes.benchmarks._machine import machine_info

SMALL_SIDE = 320
"""Width (px) of the ``small`` version (the video's 1280 scaled by a quarter)."""
FAST_STEP = 3
"""The ``fast`` version keeps every this-many-th frame."""


def dim(frames: list[np.ndarray]) -> list[np.ndarray]:
    """A quarter of the light, with sensor noise of 3 grey levels (seed 0)."""
    rng = np.random.default_rng(0)
    return [np.clip(0.25 * f + rng.normal(0.0, 3.0, f.shape), 0, 255).astype(np.uint8)
            for f in frames]


def blurred(frames: list[np.ndarray]) -> list[np.ndarray]:
    """Each frame the mean of itself and the three before it (a 4x longer exposure)."""
    return [np.mean([frames[max(i - k, 0)] for k in range(4)], axis=0).astype(np.uint8)
            for i in range(len(frames))]


def small(frames: list[np.ndarray]) -> list[np.ndarray]:
    """Scaled to :data:`SMALL_SIDE` px wide (320x180)."""
    height = round(frames[0].shape[0] * SMALL_SIDE / frames[0].shape[1])
    return [cv2.resize(f, (SMALL_SIDE, height), interpolation=cv2.INTER_AREA)
            for f in frames]


def occluded(frames: list[np.ndarray]) -> list[np.ndarray]:
    """A grey bar 120 px wide sweeping left to right over frames 150-449 (3 px a frame)."""
    out = []
    for i, f in enumerate(frames):
        f = f.copy()
        if 150 <= i < 450:
            x = 200 + 3 * (i - 150)
            f[:, x:x + 120] = 90
        out.append(f)
    return out


def compressed(frames: list[np.ndarray]) -> list[np.ndarray]:
    """Each frame through JPEG at quality 15."""
    return [cv2.imdecode(cv2.imencode(".jpg", f, [cv2.IMWRITE_JPEG_QUALITY, 15])[1],
                         cv2.IMREAD_UNCHANGED) for f in frames]


def fast(frames: list[np.ndarray]) -> list[np.ndarray]:
    """Every :data:`FAST_STEP`-th frame: the hand moves three times as far between frames
    (the same motion three times as fast, or filmed at 10 frames/s)."""
    return frames[::FAST_STEP]


DEGRADATIONS: dict[str, Callable[[list[np.ndarray]], list[np.ndarray]]] = {
    "original": list, "dim": dim, "blurred": blurred, "small": small, "occluded": occluded,
    "compressed": compressed, "fast": fast}
"""The versions tracked, by name (``original``: the video as it is)."""
STEPS = {"fast": FAST_STEP}
"""The versions that keep every n-th frame only, and n (their reference keeps the same)."""


def measure(name: str, frames: list[np.ndarray], reference: np.ndarray, width: int,
            tmp: Path) -> dict:
    """Track the version ``name`` of the video (``frames``) and score it against
    ``reference``, the keypoints (px) of the original frames ``width`` px wide, scaled to
    the version's size (pixel centres at integers)."""
    scale = frames[0].shape[1] / width
    video = write_video(frames, tmp / f"{name}.mp4")
    return {"version": name} | track_and_score(video, tmp / name,
                                               (reference + 0.5) * scale - 0.5)


def main(argv: list[str] | None = None) -> int:
    args = footage_parser(__doc__.splitlines()[0], "real_video_degraded").parse_args(argv)
    if not can_run(args.data, "real_video_degraded"):
        return 0
    machine = machine_info()
    frames = read_frames(args.data / VIDEO, args.frames)
    reference = single_hand_keypoints(frames)
    with tempfile.TemporaryDirectory() as tmp:
        rows = [measure(name, degrade(frames), reference[::STEPS.get(name, 1)],
                        frames[0].shape[1], Path(tmp))
                for name, degrade in DEGRADATIONS.items()]
    result = {"benchmark": "real_video_degraded", "machine": machine, "video": str(VIDEO),
              "reference": "MediaPipe on the original frames (still-image mode); machine "
                           "output, not truth", "runs": rows}
    save_result(result, args.json)
    for row in rows:
        print(f"{row['version']:<10} {row['size'][0]}x{row['size'][1]}: {score_line(row)}")
    print(f"-> {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
