"""Videos of one rig that disagree in length (issue 12): say so, or refuse with --strict.

``digiteyes track`` reads one video per camera and stops at the shortest. Before tracking
it counts the frames of every file (packets of the video stream, no decoding); if they
differ, or a file ends early, it warns on stderr and records ``frames_missing`` and the
warning in ``summary.json``; ``--strict`` refuses such inputs.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import av

from digiteyes.errors import DatasetError
from digiteyes.io.safe_paths import atomic_write_json


def count_frames(path: str | Path) -> int:
    """Number of video packets (frames) in the first video stream of ``path``; a file
    whose end is damaged counts the packets before the damage."""
    count = 0
    try:
        with av.open(str(path)) as container:
            if not container.streams.video:
                raise DatasetError(f"{path}: holds no video stream")
            stream = container.streams.video[0]
            try:
                for packet in container.demux(stream):
                    if packet.size:
                        count += 1
            except (av.FFmpegError, OSError):
                pass
    except (av.FFmpegError, OSError) as exc:
        raise DatasetError(f"{path}: cannot open video ({exc})") from None
    return count


def check_lengths(paths: list[str], strict: bool,
                  lengths: list[int] | None = None) -> tuple[int, str | None]:
    """The frame count of the longest input and a warning if the inputs (videos, or
    folders of images with their ``lengths`` given) differ in length (None if they agree);
    with ``strict`` a difference raises :class:`DatasetError`."""
    lengths = [count_frames(p) for p in paths] if lengths is None else list(lengths)
    longest = max(lengths)
    if min(lengths) == longest:
        return longest, None
    listing = ", ".join(f"{p}: {n}" for p, n in zip(paths, lengths, strict=True))
    warning = (f"the inputs differ in length ({listing} frames); only the first "
               f"{min(lengths)} frames can be tracked with every camera")
    if strict:
        raise DatasetError(f"{warning} (--strict)")
    print(f"digiteyes track: warning: {warning}", file=sys.stderr)
    return longest, warning


def record_missing(summary: Path, longest: int, tracked: int, warning: str | None) -> int:
    """Add ``frames_missing`` (frames of the longest video left untracked) and the warning
    to ``summary.json``; returns the count. A later end than counted counts zero."""
    missing = max(0, longest - tracked)
    try:
        payload = json.loads(summary.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return missing
    payload["frames_missing"] = missing
    payload["warnings"] = [w for w in (warning,) if w]
    atomic_write_json(summary, payload)
    if missing and warning is None:
        print(f"digiteyes track: warning: {missing} frame(s) of the videos could not be "
              "read (a file ends early or is damaged)", file=sys.stderr)
    return missing
