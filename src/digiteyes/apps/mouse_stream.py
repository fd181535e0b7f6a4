"""Where the 3D mouse's states come from: frames tracked on the fly, or a replayed track.

A *mouse stream* is an iterator of :class:`MouseFrame`: for each camera frame, the
tracked hand state mapped to the mouse pole and its buttons (:mod:`digiteyes.apps.mouse3d`,
thesis Sec. 4.3.4), the tracked hand's overlay as a JPEG, and the wall-clock times at
which the frame became available and at which its state was ready (Unix seconds), so that
the page can show the latency from frame to page.

Sources (:func:`open_mouse_stream`):

* the ``mouse`` scenario (default), rendered frame by frame and tracked as it goes: a
  first try with no camera attached;
* a dataset folder (docs/dataset.md) or a video file (with a model, rig and initial
  state), tracked frame by frame;
* a live camera (an integer index for OpenCV's ``VideoCapture``), tracked frame by frame;
* a replay (``replay=RUN_DIR``): the ``states.csv`` that ``digiteyes track`` wrote, with its
  ``overlay.mp4`` when present, nothing tracked.

The tracking itself is :class:`~digiteyes.trackers.FeatureTracker` (or any tracker given
to :func:`track_frames`), its overlay :func:`digiteyes.viz.track_overlay.overlay_image`:
the same code as ``digiteyes track``. States become the pole and buttons through a
*mapping* (:func:`mouse_mapping`): the thesis's table mapping for the reduced
``mouse-hand`` model, the palm mapping (:class:`~digiteyes.apps.palm_mouse.PalmMouse`)
for a full hand. Footage with an automatic start (a webcam and nothing else) is opened by
:func:`digiteyes.mouse_job.open_footage_mouse`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from itertools import chain, islice
from pathlib import Path

import cv2
import numpy as np

from digiteyes.apps.mouse3d import BUTTONS, TableMouse
from digiteyes.apps.palm_mouse import PalmMouse
from digiteyes.camera import Rig, load_rig
from digiteyes.errors import CameraError, DatasetError
from digiteyes.filters import OneEuroFilter, OneEuroOptions
from digiteyes.io import VideoReader, open_sequence, open_video_frames, read_state_log
from digiteyes.io.track_extras import model_of_log, track_fps, track_is_left_hand
from digiteyes.io.video import (
    DEFAULT_CAMERA_FPS,
    DEFAULT_FPS,
    frame_rate,
    open_capture_frames,
)
from digiteyes.kinematics import KinematicModel, State, load_model, resample_states
from digiteyes.kinematics.scaling import model_of_size
from digiteyes.synth import RenderOptions, render_views
from digiteyes.synth.scenarios import build_scenario
from digiteyes.trackers import FeatureTracker, FeatureTrackerOptions, warm_up
from digiteyes.trackers.base import Tracker, TrackResult
from digiteyes.viz.track_overlay import overlay_image

JPEG_QUALITY = 80
"""JPEG quality of the overlay images sent to the page (OpenCV's 0-100 scale)."""

SCENARIO_NOISE_SIGMA = 2.0
"""Sensor noise of the rendered scenario frames, grey levels (as the tracker benchmark)."""


@dataclass(frozen=True)
class MouseFrame:
    """One frame of the 3D mouse.

    Attributes
    ----------
    index : frame number from the start of the stream.
    state : (n_q,) tracked (or replayed) hand state.
    pole : (3,) pole base x, base y and height, world (table) mm.
    buttons : button name -> pressed.
    lost : the tracker flagged the track as lost in this frame.
    t_frame : when the camera frame became available, Unix seconds.
    t_state : when the state (and the overlay) was ready, Unix seconds.
    overlay_jpeg : the tracked hand's overlay image as JPEG bytes, or None.
    mapping : what turned the state into the pole and buttons (:func:`mouse_mapping`).
    """

    index: int
    state: np.ndarray
    pole: np.ndarray
    buttons: dict[str, bool]
    lost: bool
    t_frame: float
    t_state: float
    overlay_jpeg: bytes | None = None
    mapping: MouseMapping | None = field(default=None, repr=False, compare=False)

    def to_message(self) -> dict:
        """The JSON message the page receives (without the image, sent as binary)."""
        return {"type": "frame", "index": self.index,
                "pole": [float(v) for v in self.pole],
                "buttons": dict(self.buttons), "lost": self.lost,
                "t_frame_ms": 1e3 * self.t_frame, "t_state_ms": 1e3 * self.t_state,
                "has_image": self.overlay_jpeg is not None}


@dataclass
class MouseStream:
    """A source of :class:`MouseFrame`: ``frames`` plus what describes it."""

    model: KinematicModel
    frames: Iterator[MouseFrame]
    fps: float
    description: str
    total: int | None = None


def encode_jpeg(image: np.ndarray, quality: int = JPEG_QUALITY) -> bytes:
    """An RGB or grey uint8 image as JPEG bytes."""
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise CameraError(f"could not encode a {image.shape} image as JPEG")
    return data.tobytes()


MouseMapping = TableMouse | PalmMouse
"""Hand state -> pole (``pole(q)``) and buttons (``buttons(q)``)."""


def mouse_mapping(model: KinematicModel, q0: np.ndarray, *, mirrored: bool = False
                  ) -> MouseMapping:
    """The thesis's table mapping (:class:`~digiteyes.apps.mouse3d.TableMouse`) for a
    model with its button states (``mouse-hand``: world = table), else the palm mapping
    of a full hand against its start state ``q0``
    (:meth:`~digiteyes.apps.palm_mouse.PalmMouse.from_start`; ``mirrored``: a left hand
    tracked in the mirror image)."""
    if all(state in model.state_names for state in BUTTONS.values()):
        return TableMouse(model)
    return PalmMouse.from_start(model, q0, mirrored=mirrored)


def mouse_frame(mapping: MouseMapping, index: int, state: np.ndarray, lost: bool,
                t_frame: float, overlay: np.ndarray | None) -> MouseFrame:
    """Map ``state`` to the pole and buttons and encode ``overlay``; stamps ``t_state``."""
    pole = mapping.pole(state)
    buttons = {k: bool(v) for k, v in mapping.buttons(state).items()}
    jpeg = None if overlay is None else encode_jpeg(overlay)
    return MouseFrame(index, np.asarray(state, dtype=float), pole, buttons, bool(lost),
                      t_frame, time.time(), jpeg, mapping)


def smoothed(frames: Iterable[MouseFrame], model: KinematicModel, fps: float,
             options: OneEuroOptions | None = None) -> Iterator[MouseFrame]:
    """``frames`` with each state One Euro filtered online
    (:class:`~digiteyes.filters.OneEuroFilter`, restarting after a lost frame) and the pole
    and buttons taken from the filtered state by the frame's own mapping; ``t_state`` is
    stamped after the filter. The overlay keeps showing the tracked (raw) hand."""
    online = OneEuroFilter(model, fps, options)
    for frame in frames:
        state = online.follow(frame.state, frame.lost)
        mapping = frame.mapping or mouse_mapping(model, state)
        yield replace(frame, state=state, pole=mapping.pole(state),
                      buttons={k: bool(v) for k, v in mapping.buttons(state).items()},
                      t_state=time.time())


def timestamped(frames: Iterable[Sequence[np.ndarray]]) -> Iterator[tuple[float, list]]:
    """Each frame of ``frames`` with the wall-clock time it became available (Unix s)."""
    for images in frames:
        yield time.time(), list(images)


RecoverAfterStep = Callable[[Tracker, Sequence[np.ndarray], TrackResult], np.ndarray | None]
"""After each frame: the state to continue from (the tracker restarted from it) or None;
:func:`digiteyes.pipeline.recovered_state` bound to a re-detection (``apps`` sits above
``pipeline``, so the stream takes it as a callable; not the pipeline's ``Recover``, which
is the re-detection itself)."""


def track_frames(model: KinematicModel, rig: Rig, frames: Iterable[tuple[float, list]],
                 initial_state: np.ndarray, options: FeatureTrackerOptions | None = None,
                 *, overlay: bool = True, tracker: Tracker | None = None,
                 mapping: MouseMapping | None = None, recover: RecoverAfterStep | None = None,
                 first_index: int = 0) -> Iterator[MouseFrame]:
    """Track timestamped frames (from :func:`timestamped`) and yield one
    :class:`MouseFrame` per frame.

    ``tracker``: the tracker to step (None: a feature tracker with ``options``);
    ``mapping``: state -> pole and buttons (None: :func:`mouse_mapping` of the first
    frame's estimate, so that a palm mapping's origin is where the tracker puts the hand,
    not where the start did); ``recover``: see :data:`RecoverAfterStep` (None: no re-detection);
    ``first_index``: the number of the first frame (frames are numbered as the input's).
    The tracker first steps once on the first frame, untimed, and is reset
    (:func:`digiteyes.trackers.warm_up`): compiling or loading the kernels happens before
    the first frame's clock starts, so it never shows as frame-to-page latency."""
    tracker = tracker or FeatureTracker(model, rig, options or FeatureTrackerOptions())
    frames = iter(frames)
    first = next(frames, None)
    if first is None:
        return
    warm_up(tracker, first[1], initial_state)
    tracker.reset(np.asarray(initial_state, dtype=float))
    restamped = (time.time(), first[1])
    for index, (t_frame, images) in enumerate(chain([restamped], frames), start=first_index):
        result = tracker.step(images)
        fresh = recover(tracker, images, result) if recover is not None else None
        state = result.state if fresh is None else fresh
        mapping = mapping or mouse_mapping(model, state, mirrored=rig.mirrored)
        image = overlay_image(images, result, rig, model) if overlay else None
        yield mouse_frame(mapping, index, state, result.lost, t_frame, image)


def render_scenario_frames(name: str = "mouse", seed: int = 0, n_frames: int | None = None,
                           speed: float = 1.0) -> tuple[object, Iterator[list[np.ndarray]]]:
    """A scenario and its frames rendered one at a time (grey, black cloth, sensor noise
    :data:`SCENARIO_NOISE_SIGMA`, seeds as ``digiteyes render --seed``).

    ``speed`` > 1 plays the motion faster: frame t shows the true state at time
    ``speed * t`` (linear interpolation between the scenario's frames), so every motion
    covers the same path in fewer frames. Returns ``(scenario, frames)``; the scenario's
    ``states`` are then the states shown.
    """
    scenario = build_scenario(name, seed=seed)
    if speed != 1.0:
        scenario = resample_scenario(scenario, speed)
    if n_frames is not None:
        scenario = replace(scenario, states=scenario.states[:n_frames])
    return scenario, render_frames(scenario, seed)


def render_frames(scenario, seed: int = 0) -> Iterator[list[np.ndarray]]:
    """The frames of ``scenario.states`` rendered one at a time through its rig (grey,
    black cloth, noise :data:`SCENARIO_NOISE_SIGMA`, seeds as ``digiteyes render``)."""
    options = RenderOptions(background="black", noise_sigma=SCENARIO_NOISE_SIGMA,
                            background_seed=seed)
    for t, q in enumerate(scenario.states):
        views = render_views(scenario.model, q, scenario.rig, options,
                             np.random.default_rng([seed, t]))
        yield [v.image for v in views]


def resample_scenario(scenario, speed: float):
    """``scenario`` played ``speed`` times faster: its states at times ``0, speed,
    2 speed, ...`` (frames), interpolated on the state manifold
    (:func:`~digiteyes.kinematics.resample_states`)."""
    if speed <= 0:
        raise DatasetError(f"speed must be positive, got {speed}")
    return replace(scenario, states=resample_states(scenario.model, scenario.states, speed))


def replay_frames(run_dir: str | Path, model: KinematicModel, fps: float
                  ) -> Iterator[MouseFrame]:
    """The states of a finished run (``run_dir/states.csv``) with the frames of its
    ``overlay.mp4`` when there is one, paced at ``fps`` frames per second; mapped by
    :func:`mouse_mapping` of the run's first state (a full hand's palm mapping starts
    from it; a left hand's run holds the mirror image's states, ``summary.json``), the
    hand drawn at its size over the run (:attr:`~digiteyes.io.StateLog.median_hand_scale`:
    a keypoint track's measured hand)."""
    folder = Path(run_dir)
    log = read_state_log(folder / "states.csv", model)
    model = model_of_size(model, log.median_hand_scale)
    mapping = (mouse_mapping(model, log.states[0], mirrored=track_is_left_hand(folder))
               if len(log.states) else None)
    video_path = folder / "overlay.mp4"
    reader = VideoReader(video_path) if video_path.is_file() else None
    period = 1.0 / fps
    start = time.time()
    try:
        for index, (q, lost) in enumerate(zip(log.states, log.lost, strict=True)):
            due = start + index * period
            if (wait := due - time.time()) > 0:
                time.sleep(wait)
            image = reader.read() if reader is not None else None
            yield mouse_frame(mapping, index, q, bool(lost), time.time(), image)
    finally:
        if reader is not None:
            reader.close()


def paced(frames: Iterable[list[np.ndarray]], fps: float) -> Iterator[list[np.ndarray]]:
    """``frames`` released no faster than ``fps`` per second (a camera's clock for frames
    that come from files or the renderer); late frames go out at once."""
    period = 1.0 / fps
    start = time.monotonic()
    for index, images in enumerate(frames):
        if (wait := start + index * period - time.monotonic()) > 0:
            time.sleep(wait)
        yield images


def camera_frames(index: int, rig: Rig) -> tuple[Iterator[list[np.ndarray]], float | None]:
    """Grey frames of live camera ``index`` (:func:`digiteyes.io.video.open_capture_frames`,
    the reader of ``digiteyes track --camera``), checked against the one-camera ``rig``,
    and the frame rate the camera reports (None when it reports none)."""
    captured = open_capture_frames(index, gray=True)

    def checked() -> Iterator[list[np.ndarray]]:
        for images in captured:
            rig.check_images(images)
            yield images

    return checked(), captured.fps


def open_mouse_stream(source: str | None = None, *, replay: str | Path | None = None,
                      model_name: str | None = None, rig_path: str | None = None,
                      init_path: str | None = None, frames: int | None = None,
                      fps: float | None = None, iterations: int = 5, seed: int = 0,
                      overlay: bool = True,
                      smooth: OneEuroOptions | None = None) -> MouseStream:
    """Resolve a ``digiteyes mouse`` source into a :class:`MouseStream`; with ``smooth``
    the states (and so the pole and buttons) are One Euro filtered online
    (:func:`smoothed`). The other parameters are those of :func:`_open_source`."""
    stream = _open_source(source, replay=replay, model_name=model_name, rig_path=rig_path,
                          init_path=init_path, frames=frames, fps=fps,
                          iterations=iterations, seed=seed, overlay=overlay)
    if smooth is None:
        return stream
    return replace(stream, frames=smoothed(stream.frames, stream.model, stream.fps, smooth))


def _open_source(source: str | None = None, *, replay: str | Path | None = None,
                 model_name: str | None = None, rig_path: str | None = None,
                 init_path: str | None = None, frames: int | None = None,
                 fps: float | None = None, iterations: int = 5, seed: int = 0,
                 overlay: bool = True) -> MouseStream:
    """Resolve a ``digiteyes mouse`` source into a :class:`MouseStream` (no smoothing).

    Parameters
    ----------
    source : None (the ``mouse`` scenario rendered and tracked on the fly), a dataset
        folder, a video file (needs ``model_name``, ``rig_path``, ``init_path``) or a camera
        index such as ``"0"`` (needs the same).
    replay : a ``digiteyes track`` output folder to replay instead of tracking.
    frames : stop after this many frames (None: the whole source).
    fps : frames per second to pace files, the scenario and replays at (None: the
        source's rate: a video's declared rate, a replayed run's ``summary.json`` rate,
        else 10 Hz); live cameras run at their own rate.
    iterations : Gauss-Newton iterations per frame (the mouse needs several, docs/mouse3d.md).
    """
    options = FeatureTrackerOptions(iterations_per_frame=iterations)
    if replay is not None:
        model = load_model(model_name) if model_name else model_of_log(
            Path(replay) / "states.csv")
        rate = fps or track_fps(replay) or DEFAULT_FPS
        stream = replay_frames(replay, model, rate)
        return MouseStream(model, _limit(stream, frames), rate, f"replay of {replay}", frames)
    if source is None:
        scenario, rendered = render_scenario_frames("mouse", seed=seed, n_frames=frames)
        rate = fps or scenario.fps
        stream = track_frames(scenario.model, scenario.rig, timestamped(paced(rendered, rate)),
                              scenario.initial_state, options, overlay=overlay)
        return MouseStream(scenario.model, stream, rate,
                           f"the mouse scenario (seed {seed}), rendered and tracked on the fly",
                           scenario.n_frames)
    path = Path(source)
    if path.is_dir():
        dataset = open_sequence(path)
        model = load_model(model_name) if model_name else dataset.model
        rig = load_rig(rig_path) if rig_path else dataset.rig
        initial = (State.load_json(model, init_path).q if init_path
                   else State(model, dataset.initial_state).q)
        rate = fps or dataset.fps
        total = dataset.n_frames if frames is None else min(frames, dataset.n_frames)
        raw = paced(islice(iter(dataset), total), rate)
        return MouseStream(model, track_frames(model, rig, timestamped(raw), initial, options,
                                               overlay=overlay),
                           rate, f"dataset {path}", total)
    if not (model_name and rig_path and init_path):
        raise DatasetError(f"{source}: a video or camera needs --model, --rig and --init")
    model = load_model(model_name)
    rig = load_rig(rig_path)
    initial = State.load_json(model, init_path).q
    if source.isdigit():
        if len(rig) != 1:
            raise CameraError(f"{rig_path}: a live camera needs a one-camera rig, got "
                              f"{len(rig)}")
        raw, reported = camera_frames(int(source), rig)
        rate = fps or reported or DEFAULT_CAMERA_FPS
        description = f"camera {source}"
    else:
        if not path.is_file():
            raise DatasetError(f"{source}: no such video file, dataset folder or camera index")
        if len(rig) != 1:
            raise CameraError(f"{rig_path}: one video needs a one-camera rig, got {len(rig)}")
        rate = fps or frame_rate(path) or DEFAULT_FPS
        raw = paced(open_video_frames([path], gray=True), rate)
        description = f"video {path}"
    raw = islice(raw, frames) if frames is not None else raw
    return MouseStream(model, track_frames(model, rig, timestamped(raw), initial, options,
                                           overlay=overlay), rate, description, frames)


def _limit(stream: Iterator[MouseFrame], frames: int | None) -> Iterator[MouseFrame]:
    return stream if frames is None else islice(stream, frames)
