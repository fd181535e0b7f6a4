"""Input and output: sequence folders (frames, rig, model, ground truth), state logs, video.

See docs/dataset.md for the on-disk format.
"""

from digiteyes.io.dataset import (
    FrameTruth,
    GroundTruth,
    Sequence,
    SequenceWriter,
    open_sequence,
    read_png,
)
from digiteyes.io.state_log import StateLog, StateLogWriter, read_state_log
from digiteyes.io.video import VideoReader, VideoWriter, open_video_frames

__all__ = [
    "FrameTruth", "GroundTruth", "Sequence", "SequenceWriter", "StateLog", "StateLogWriter",
    "VideoReader", "VideoWriter", "open_sequence", "open_video_frames", "read_png",
    "read_state_log",
]
