"""Real-data benchmark: the real video with a second hand in view; is the asked hand tracked?

Usage::

    python benchmarks/real_two_hands.py [--data ../shared/data] [--frames N] [--json FILE]
        [--shift-px PX]

The real video (``real_video/human_hand_video.mp4``, a right hand) gets a second hand: in
every frame ``t`` the hand of frame ``t + 150`` of the same video, mirrored (so a left hand)
and moved :data:`SHIFT_PX` to the left, is pasted where it differs from the wall, inside
the region MediaPipe's keypoints of that frame outline (the hand and its forearm). Both
hands then move, each on its own. ``digiteyes track VIDEO --hand left`` and ``--hand
right`` (:func:`digiteyes.track_job.run_track_job`, the keypoint tracker, automatic start,
one core) should each follow their own hand. Per run: the share of frames whose tracked
hand lies on the asked one (the worst digit's mean keypoint distance under half a palm
length from MediaPipe's keypoints of that hand in the single-hand frames, still-image
mode: machine output, not truth), the median and 90th percentile of that distance, the
frames flagged lost, re-detections and frames per second.

Without the data or the MediaPipe extra the script says so and exits with status 0.
"""

from __future__ import annotations

import one_thread  # noqa: F401  (first: one thread for the libraries imported below)

# isort: split
import sys
import tempfile
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

LAG_FRAMES = 150
"""The second hand is the video's hand this many frames later."""
SHIFT_PX = -420
"""How far the mirrored second hand is moved sideways (px; negative: to the left)."""
PICTURE_FRAME = 300
"""The frame ``--picture`` writes."""
WALL_DIFFERENCE = 40
"""Grey levels by which a pixel must differ from the wall's median colour to be pasted."""


def hand_region(keypoints: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """(H, W) float mask: the keypoints' hull grown by a third of a palm length, and the
    forearm (a thick line from the wrist away from the middle finger)."""
    mask = np.zeros(shape, np.uint8)
    if np.isnan(keypoints).any():
        return mask.astype(np.float32)
    palm = float(np.linalg.norm(keypoints[0] - keypoints[9]))
    cv2.fillConvexPoly(mask, cv2.convexHull(keypoints.astype(np.int32)), 1)
    size = int(0.35 * palm) | 1
    mask = cv2.dilate(mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size)))
    wrist, away = keypoints[0], (keypoints[0] - keypoints[9]) / max(palm, 1.0)
    cv2.line(mask, tuple(wrist.astype(int)), tuple((wrist + 3 * palm * away).astype(int)), 1,
             max(int(0.8 * palm), 1))
    return mask.astype(np.float32)


def paste_second_hand(images: list[np.ndarray], keypoints: np.ndarray,
                      shift_px: int = SHIFT_PX) -> tuple[list[np.ndarray], np.ndarray]:
    """The frames with the second hand (module docstring; moved ``shift_px`` sideways)
    and its keypoints (T, 21, 2)."""
    n = len(images)
    height, width = images[0].shape[:2]
    second = keypoints[(np.arange(n) + LAG_FRAMES) % n].copy()
    second[..., 0] = width - 1 - second[..., 0] + shift_px
    out = []
    for t, base in enumerate(images):
        other = np.roll(images[(t + LAG_FRAMES) % n][:, ::-1], shift_px, axis=1)
        wall = np.median(other.reshape(-1, 3)[::97], axis=0)
        differs = (np.abs(other.astype(np.int16) - wall.astype(np.int16)).max(axis=2)
                   > WALL_DIFFERENCE).astype(np.uint8)
        differs = cv2.morphologyEx(differs, cv2.MORPH_OPEN, np.ones((5, 5), np.uint8))
        differs = cv2.morphologyEx(differs, cv2.MORPH_CLOSE, np.ones((9, 9), np.uint8))
        alpha = cv2.GaussianBlur(differs.astype(np.float32) * hand_region(second[t], (height,
                                                                                      width)),
                                 (7, 7), 0)[..., None]
        if shift_px < 0:
            alpha[:, shift_px:] = 0  # what the roll wrapped round
        elif shift_px > 0:
            alpha[:, :shift_px] = 0
        out.append((alpha * other + (1 - alpha) * base).astype(np.uint8))
    return out, second


def main(argv: list[str] | None = None) -> int:
    parser = footage_parser(__doc__.splitlines()[0], "real_two_hands")
    parser.add_argument("--shift-px", type=int, default=SHIFT_PX,
                        help=f"how far the second hand is moved sideways (px; default "
                             f"{SHIFT_PX}; -80 brings the hands within a finger's width)")
    parser.add_argument("--picture", type=Path, default=None,
                        help=f"also write frame {PICTURE_FRAME} of the two-hand video here, half "
                             "size")
    args = parser.parse_args(argv)
    if not can_run(args.data, "real_two_hands"):
        return 0
    machine = machine_info()
    images = read_frames(args.data / VIDEO, args.frames)
    right = single_hand_keypoints(images)
    composed, left = paste_second_hand(images, right, args.shift_px)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        video = write_video(composed, Path(tmp) / "two_hands.mp4")
        if args.picture is not None:  # half size: a picture for the docs
            half = cv2.resize(composed[min(PICTURE_FRAME, len(composed) - 1)], None, fx=0.5,
                              fy=0.5, interpolation=cv2.INTER_AREA)
            cv2.imwrite(str(args.picture), cv2.cvtColor(half, cv2.COLOR_RGB2BGR),
                        [cv2.IMWRITE_JPEG_QUALITY, 85])
        for hand, reference in (("right", right), ("left", left)):
            rows.append({"hand": hand} | track_and_score(video, Path(tmp) / hand, reference,
                                                         hand))
    result = {"benchmark": "real_two_hands", "machine": machine, "video": str(VIDEO),
              "second_hand": {"lag_frames": LAG_FRAMES, "shift_px": args.shift_px,
                              "mirrored": True},
              "reference": "MediaPipe on the single-hand frames (still-image mode); machine "
                           "output, not truth", "runs": rows}
    save_result(result, args.json)
    for row in rows:
        print(f"two hands, --hand {row['hand']}: {score_line(row)}")
    print(f"-> {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
