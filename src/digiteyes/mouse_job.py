"""``digiteyes mouse VIDEO`` or ``digiteyes mouse 0`` with nothing else: the 3D mouse on
footage, started automatically (ours; docs/mouse3d.md, "From a webcam, no set-up").

The thesis's mouse needs a calibrated table camera, the reduced model and a start state
(:func:`digiteyes.apps.mouse_stream.open_mouse_stream` with ``--model``, ``--rig``,
``--init``). Here the footage alone is enough, as for ``digiteyes track``:

1. the camera is the rig file when given, else
   :func:`~digiteyes.camera.default.default_camera` of the first frame's size;
2. the model is the full hand (or ``--model``, any model with the 21 hand keypoints);
3. the start is searched frame by frame until a hand shows
   (:func:`~digiteyes.detect.initialiser.start_automatically`); a left hand is tracked
   as the right hand of the mirror image (:func:`digiteyes.track_job.as_left_hand`);
   with two or more cameras the hand's size is measured there and a model of that size
   is tracked and mapped (:meth:`~digiteyes.detect.initialiser.AutoInitialiser.
   size_hand`, as ``track --init auto``);
4. the tracker is the one ``digiteyes track --tracker auto`` picks for footage
   (:func:`~digiteyes.track_job.resolve_tracker`: the keypoint tracker with MediaPipe
   installed, the feature tracker otherwise), re-detecting after a lost frame
   (:func:`~digiteyes.pipeline.recovered_state`);
5. states become the pole and buttons by the palm mapping of the first tracked state
   (:class:`~digiteyes.apps.palm_mouse.PalmMouse`): the hand's own pose is the table.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from itertools import chain, islice
from pathlib import Path

import numpy as np

from digiteyes.apps.mouse_stream import (
    MouseFrame,
    MouseStream,
    paced,
    timestamped,
    track_frames,
)
from digiteyes.camera import Rig, load_rig
from digiteyes.camera.default import default_camera
from digiteyes.detect.side import TRACKED_SIDE
from digiteyes.errors import DatasetError
from digiteyes.io import open_video_frames
from digiteyes.io.video import DEFAULT_CAMERA_FPS, DEFAULT_FPS, frame_rate, open_capture_frames
from digiteyes.kinematics import KinematicModel, load_model
from digiteyes.pipeline import recovered_state
from digiteyes.track_job import (
    AUTO_TRACKER,
    DEFAULT_MODEL,
    FOOTAGE_TRACKER,
    as_left_hand,
    has_hand21,
    resolve_tracker,
)
from digiteyes.trackers import create_tracker

MOUSE_FIT_ITERATIONS = 10
"""The keypoint tracker's fit iterations per frame for the mouse: twice ``track``'s
default, for a steadier cursor (``bench mouse`` section e, hand-mouse flesh render: pole
jitter 4.2 / 9.6 mm per frame at 5, 3.7 / 8.0 at 10; thumb button 91 -> 97 %), which a
webcam's 30 frames/s affords. Footage's start took its depth from the model's size, so no
size is read from it (``start_size`` off, as ``track`` does on footage)."""


def open_footage_mouse(source: str, *, model_name: str | None = None,
                       rig_path: str | None = None, frames: int | None = None,
                       fps: float | None = None, overlay: bool = True,
                       detector: str = "auto") -> MouseStream:
    """The mouse stream of a video file or live camera index ``source`` (module
    docstring). ``frames`` bounds the frames read (the start's search included), ``fps``
    paces a video (default: its own rate; a camera runs at its own). Raises
    :class:`DatasetError` for a missing file, a model without the hand keypoints, or
    footage that ends before a hand shows."""
    model = load_model(model_name or DEFAULT_MODEL)
    if not has_hand21(model):
        raise DatasetError(f"model {model.name!r} lacks the 21 hand keypoints an automatic "
                           "start fits; give --rig and --init for it, or use a full hand model")
    if source.isdigit():
        captured = open_capture_frames(int(source))
        rate = fps or captured.fps or DEFAULT_CAMERA_FPS
        raw: Iterator[list[np.ndarray]] = captured
        description = f"camera {source}"
    else:
        path = Path(source)
        if not path.is_file():
            raise DatasetError(f"{source}: no such video file, dataset folder or camera index")
        rate = fps or frame_rate(path) or DEFAULT_FPS
        raw = paced(open_video_frames([path]), rate)
        description = f"video {path}"
    if frames is not None:
        raw = islice(raw, frames)
    rig = load_rig(rig_path) if rig_path else None
    stream = footage_mouse_frames(model, raw, rig, detector, overlay)
    return MouseStream(model, stream, rate, f"{description}, full hand, automatic start",
                       frames)


def footage_mouse_frames(model: KinematicModel, frames: Iterable[list[np.ndarray]],
                         rig: Rig | None = None, detector: str = "auto", overlay: bool = True
                         ) -> Iterator[MouseFrame]:
    """Find the hand in RGB frames (one list of images per time step, read lazily, e.g.
    from a camera), then track it and map each state (module docstring, steps 1 and 3-5;
    ``rig`` None: the default camera of the first frame's size). Runs when the first
    frame is asked for, so the search for a hand happens while someone is watching. A
    frame's time is when it was read after the start (the start frame's, when tracking
    begins); each :class:`MouseFrame`'s ``index`` is its frame's number in ``frames``."""
    from digiteyes.detect.initialiser import AutoInitialiser, start_automatically

    frames = iter(frames)
    first = next(frames, None)
    if first is None:
        return
    rig = rig or Rig((default_camera(first[0].shape[1], first[0].shape[0]),))
    rig.check_images(first)
    initialiser = AutoInitialiser(model, rig, detector)  # any side: the start's decides
    initial, skipped, found = start_automatically(initialiser, chain([first], frames))
    if initialiser.last.sides() == {"left"}:
        initialiser, rig, found, initial = as_left_hand(initialiser, rig, found, initial)
    initialiser.side = TRACKED_SIDE
    initial, scale = initialiser.size_hand(initial)  # two cameras: the hand's own size
    if scale != 1.0:
        model = initialiser.model
    name = resolve_tracker(AUTO_TRACKER, True, detector, model)
    options = ({"detector": detector, "start_size": False, "iterations": MOUSE_FIT_ITERATIONS}
               if name == FOOTAGE_TRACKER else {})
    tracker = create_tracker(name, model, rig, **options)
    yield from track_frames(
        model, rig, timestamped(found), initial, tracker=tracker, overlay=overlay,
        recover=lambda t, images, result: recovered_state(t, images, result, initialiser),
        first_index=skipped)
