"""Real-data benchmark: MediaPipe on real images made grey, with and without the skin tint,
and upright or also turned.

Usage::

    python benchmarks/real_grey.py [--data ../shared/data] [--json FILE]

A monochrome camera (the thesis's) or a grey dataset gives MediaPipe no skin hue, and it
misses hands it finds in colour. :class:`~digiteyes.detect.mediapipe_detector.
MediaPipeDetector` therefore looks again, at the image tinted to skin
(:func:`~digiteyes.detect.mediapipe_detector.skin_tinted`), where it finds no hand in a
grey image (``grey_as_skin``). In still-image mode it also looks at an image without a
hand turned by quarter turns (``look_turned``). Two measurements, on one core:

* **Detection** (still-image mode) on the real video (every :data:`VIDEO_STEP`-th frame),
  the annotated images and the STB pair, in colour and made grey (OpenCV's RGB-to-grey):
  hands found in colour upright and with the turned looks, in grey alone, in every image
  tinted, with the tint's rule, and with the rule and the turned looks (the detector's
  defaults). A hand found in a grey image, or only turned, counts when its palm lies
  within half a palm length of the upright colour image's detection (or anywhere when
  that found none).
* **Tracking** the real video made grey (``digiteyes track --init auto``, what ``auto``
  runs on footage: the keypoint tracker), with the rule and with every frame tinted,
  against the colour video's track: frames tracked and lost, and the distance of the
  tracked keypoints from the colour track's in the image (mean over the model keypoints,
  px; median and 90th percentile over frames). The colour track is not truth.

Results go to ``benchmarks/results/real_grey.json``. Without the data or the MediaPipe
extra the script says so and exits with status 0.
"""

from __future__ import annotations

import one_thread  # noqa: F401  (first: one thread for the libraries imported below)

# isort: split
import argparse
import csv
import json
import sys
import tempfile
from collections.abc import Callable
from itertools import islice
from pathlib import Path

import cv2
import numpy as np
from real_video import DEFAULT_DATA, RESULTS, VIDEO

from digiteyes.benchmarks._machine import machine_info
from digiteyes.detect.check import palm_gap
from digiteyes.detect.mediapipe_detector import (
    MediaPipeDetector,
    mediapipe_available,
    skin_tinted,
)
from digiteyes.io.video import VideoReader, VideoWriter, frame_rate
from digiteyes.track_job import TrackJob, run_track_job

IMAGES = (("FreiHAND", "annotated_images/tests/data/freihand", "*.jpg"),
          ("InterHand2.6M", "annotated_images/tests/data/interhand2.6m", "*.jpg"),
          ("OneHand10K", "annotated_images/tests/data/onehand10k", "*.jpg"),
          ("Panoptic", "annotated_images/tests/data/panoptic", "*.jpg"),
          ("STB pair", "stb_sample/images", "**/*.png"))
VIDEO_STEP = 6
"""Every how many frames of the real video the detection is measured."""


def detection_counts(images: list[np.ndarray]) -> dict[str, int]:
    """Hands found in ``images`` (RGB) in colour, upright and also turned, and made grey:
    alone, always tinted, with the tint's rule, with the rule and the turned looks
    (module docstring)."""
    plain = MediaPipeDetector(max_hands=1, grey_as_skin=False, look_turned=False)
    rule = MediaPipeDetector(max_hands=1, look_turned=False)
    turned = MediaPipeDetector(max_hands=1, grey_as_skin=False)
    full = MediaPipeDetector(max_hands=1)  # the defaults: the tint's rule, turned looks
    counts = {"images": len(images), "colour": 0, "colour_turned": 0, "grey": 0,
              "always_tinted": 0, "rule": 0, "rule_turned": 0}
    for rgb in images:
        colour = plain.detect(rgb)
        grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        counts["colour"] += bool(colour)
        for key, found in (("colour_turned", colour or turned.detect(rgb)),
                           ("grey", plain.detect(grey)),
                           ("always_tinted", plain.detect(skin_tinted(grey))),
                           ("rule", rule.detect(grey)),
                           ("rule_turned", full.detect(grey))):
            counts[key] += bool(found) and (
                not colour or palm_gap(colour[0].keypoints, found[0].keypoints) < 0.5)
    for detector in (plain, rule, turned, full):
        detector.close()
    return counts


def write_video(source: Path, target: Path, convert: Callable[[np.ndarray], np.ndarray]
                ) -> None:
    """``source`` with every frame converted (RGB to RGB), as a video at its frame rate
    (the library's reader and writer: H.264)."""
    with VideoReader(source) as reader, VideoWriter(target, frame_rate(source) or 30.0,
                                                     codec="h264") as writer:
        for rgb in reader:
            writer.write(convert(rgb))


def grey_rgb(rgb: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY), cv2.COLOR_GRAY2RGB)


def tinted_rgb(rgb: np.ndarray) -> np.ndarray:
    return skin_tinted(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY))


def tracked_pixels(video: Path, out: Path) -> tuple[np.ndarray, np.ndarray, dict]:
    """Track ``video`` as ``digiteyes track VIDEO --init auto`` does; its frame numbers,
    keypoint pixels (T, K, 2) from ``keypoints.csv`` and summary."""
    run_track_job(TrackJob(inputs=(str(video),), output=str(out), init_path="auto",
                           overlay=False, progress=False))
    with open(out / "keypoints.csv", newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))
    header, values = rows[0], np.array(rows[1:], dtype=float)
    u = [i for i, name in enumerate(header) if name.endswith(".u_px")]
    pixels = np.stack([values[:, u], values[:, [i + 1 for i in u]]], axis=-1)
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    return values[:, 0].astype(int), pixels, summary


def track_comparison(video: Path, tmp: Path) -> dict[str, dict]:
    """The real video tracked in colour, made grey (the rule) and tinted throughout; the
    grey runs' keypoints against the colour run's (module docstring)."""
    runs = {"colour": video}
    for name, convert in (("grey", grey_rgb), ("tinted_throughout", tinted_rgb)):
        runs[name] = tmp / f"{name}.mp4"
        write_video(video, runs[name], convert)
    tracks = {name: tracked_pixels(path, tmp / f"{name}-track") for name, path in runs.items()}
    frames_c, pixels_c, _ = tracks["colour"]
    out = {}
    for name, (frames, pixels, summary) in tracks.items():
        common, ours, theirs = np.intersect1d(frames, frames_c, return_indices=True)
        gap = np.linalg.norm(pixels[ours] - pixels_c[theirs], axis=-1).mean(axis=1)
        out[name] = {"frames_tracked": len(frames), "lost_frames": summary["lost_frames"],
                     "re_detections": summary["reinitialisations"],
                     "tracker": summary["tracker"],
                     "gap_to_colour_track_px": {"median": float(np.median(gap)),
                                                "p90": float(np.percentile(gap, 90)),
                                                "frames": len(common)}}
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DEFAULT_DATA)
    parser.add_argument("--json", type=Path, default=RESULTS / "real_grey.json")
    args = parser.parse_args(argv)
    if not (args.data / VIDEO).is_file():
        print(f"real_grey: no {VIDEO} under {args.data}; skipped")
        return 0
    if not mediapipe_available():
        print('real_grey: needs the MediaPipe extra (pip install "digiteyes[mediapipe]"); '
              "skipped")
        return 0
    machine = machine_info()
    sources = {f"real video, every {VIDEO_STEP}th frame":
               list(islice(VideoReader(args.data / VIDEO), 0, None, VIDEO_STEP))}
    for name, folder, pattern in IMAGES:
        paths = sorted((args.data / folder).glob(pattern))
        sources[name] = [cv2.cvtColor(cv2.imread(str(p)), cv2.COLOR_BGR2RGB) for p in paths]
    detection = {name: detection_counts(images) for name, images in sources.items() if images}
    detection["all"] = {key: sum(c[key] for c in detection.values())
                        for key in next(iter(detection.values()))}
    with tempfile.TemporaryDirectory() as tmp:
        tracking = track_comparison(args.data / VIDEO, Path(tmp))
    result = {"benchmark": "real_grey", "machine": machine, "detection": detection,
              "tracking": tracking}
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(result, indent=2) + "\n", encoding="utf-8")
    print("MediaPipe on real images made grey (hands found; still-image mode)")
    print(f"{'images':32s} {'n':>4s} {'colour':>7s} {'+turned':>8s} {'grey':>5s} "
          f"{'tinted':>7s} {'rule':>5s} {'+turned':>8s}")
    for name, c in detection.items():
        print(f"{name:32s} {c['images']:4d} {c['colour']:7d} {c['colour_turned']:8d} "
              f"{c['grey']:5d} {c['always_tinted']:7d} {c['rule']:5d} {c['rule_turned']:8d}")
    print("\nthe real video tracked (--init auto), against the colour video's track")
    for name, row in tracking.items():
        gap = row["gap_to_colour_track_px"]
        print(f"{name:18s} {row['tracker']}: {row['frames_tracked']} frames, "
              f"{row['lost_frames']} lost, {row['re_detections']} re-detections; keypoints "
              f"{gap['median']:.1f} px from the colour track (median; p90 {gap['p90']:.1f})")
    print(f"-> {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
