"""One tracking job and the one function that runs it (:func:`run_track_job`).

A :class:`TrackJob` holds what ``digiteyes track`` was asked to do: the input (a dataset
folder, one video per camera, or a live camera), the tracker and its options, the start
(the dataset's state, a state file, or ``"auto"``: detect and fit), and the outputs.
``digiteyes track`` is a command line over :func:`run_track_job`; ``digiteyes track-many``
(:mod:`digiteyes.track_many`) runs one job per input as a Ray task, and the mouse app reads
live cameras through the same :func:`~digiteyes.io.video.open_capture_frames`.

:func:`run_track_job` opens the input, resolves the model, rig and initial state, creates
the tracker from the registry, and hands the frames to
:func:`digiteyes.pipeline.run_tracker` (outputs listed there) with the frame sinks asked
for (``keypoints.csv`` always; the JSON-lines stream; the live window), then writes the
joint angles, the smoothed states and the report page.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass, fields
from itertools import chain, islice
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from tqdm import tqdm

from digiteyes.camera import Rig, load_rig
from digiteyes.camera.default import DEFAULT_HFOV_DEG, default_camera
from digiteyes.camera.mirror import mirror_images, mirrored_rig
from digiteyes.camera.working_size import DEFAULT_MAX_SIDE, resize_images, working_rig
from digiteyes.detect.side import TRACKED_SIDE
from digiteyes.errors import CameraError, DatasetError, DigitEyesError
from digiteyes.features import FeatureOptions
from digiteyes.filters import OneEuroOptions
from digiteyes.io import open_sequence, open_video_frames
from digiteyes.io.frame_sinks import (
    KEYPOINTS_FILE,
    CameraKeypoints,
    JsonLinesStream,
    KeypointLog,
)
from digiteyes.io.image_folder import is_image_folder, open_image_folder_frames
from digiteyes.io.safe_paths import atomic_write_json
from digiteyes.io.track_extras import write_track_extras, write_track_model
from digiteyes.io.video import (
    DEFAULT_CAMERA_FPS,
    DEFAULT_FPS,
    frame_rate,
    open_capture_frames,
)
from digiteyes.io.video_lengths import check_lengths, record_missing
from digiteyes.jsonfile import read_json_object
from digiteyes.kinematics import KinematicModel, State, load_model
from digiteyes.pipeline import FrameSink, TrackingRun, run_tracker
from digiteyes.trackers import (
    DEFAULT_TRACKER,
    FeatureTrackerOptions,
    Tracker,
    all_features,
    create_tracker,
    sizes_hand,
    thesis_whole_hand_links,
    tracker_entry,
)

if TYPE_CHECKING:
    from digiteyes.detect.check import DetectionCheck
    from digiteyes.detect.initialiser import AutoInitialiser

AUTO = "auto"
"""``init_path`` value that starts from a detection and model fit (``--init auto``)."""
AUTO_HAND = "auto"
"""``hand`` value that takes the side the detector reports at the automatic start."""
AUTO_TRACKER = "auto"
"""``tracker_name`` value that lets :func:`resolve_tracker` choose."""
DEFAULT_CHECK_EVERY = 3
"""Frames between the detector's checks of a track on footage (``--check-every``)."""
FOOTAGE_TRACKER = "keypoints"
"""The tracker ``auto`` chooses for footage when a learned detector is installed."""
DATASET_TRACKER = "features+keypoints"
"""The tracker ``auto`` chooses for a dataset whose hand a learned detector finds where
its start is: the feature tracker with the detector's keypoints in its solves
(docs/anchored-features.md), the most accurate on the flesh hand's renders (mean
fingertip error over the accuracy table 14.3 mm, the keypoint tracker 16.2) and before a
cluttered backdrop; too slow for footage's 60 frames/s at 1280x720."""
DEFAULT_MODEL = "hand"
"""Model of videos and cameras when none is named."""


def tracker_options(iterations: int, window: float, links: str, model: KinematicModel,
                    robust: str | None, prediction: str, shading: bool = True
                    ) -> FeatureTrackerOptions:
    """Feature-tracker settings from the command-line choices (shared with ``demo``).

    ``links`` is ``"default"``, ``"all"`` or ``"thesis"`` (thesis Sec. 4.3.3's set);
    ``window`` the feature search window (px); ``robust`` None, ``"huber"`` or ``"tukey"``.
    """
    chosen = {"default": None, "all": all_features(model),
              "thesis": thesis_whole_hand_links(model)}[links]
    return FeatureTrackerOptions(
        iterations_per_frame=iterations,
        features=FeatureOptions(window_px=window),
        links=chosen,
        robust_loss=robust,
        prediction=prediction,
        shading_correction=shading,
    )


@dataclass(frozen=True)
class TrackJob:
    """What ``digiteyes track`` was asked to do (plain values: it travels to Ray workers).

    Attributes
    ----------
    inputs : one dataset folder, or one video file per camera of the rig, in rig order
        (empty with ``camera``).
    output : output folder.
    model_name, rig_path : override the dataset's model and rig; for videos and cameras
        the model defaults to :data:`DEFAULT_MODEL` and the rig to one
        :func:`~digiteyes.camera.default.default_camera` of field of view ``hfov``.
    init_path : a state JSON, :data:`AUTO` (detect and fit), or None (the dataset's;
        for footage, :data:`AUTO`).
    iterations, window, links, robust, prediction, shading : the feature tracker's flags
        (:func:`tracker_options`).
    max_frames : track at most this many frames (None: all).
    fps : overlay video and smoothing frame rate (None: the dataset's or the first video's,
        else :data:`DEFAULT_FPS`).
    overlay : write the overlay video; progress : show a progress bar.
    tracker_name : a registered tracker, or ``"auto"`` (:func:`resolve_tracker`);
        options : ``(key, value)`` pairs of its options
        (on top of the flags for the feature tracker).
    strict : refuse videos of different lengths.
    smooth : One Euro settings of the smoothed outputs (None: none written).
    camera : a live camera index to read instead of ``inputs``.
    show : show the overlay in a window; stream : ``"-"`` or ``"tcp://HOST:PORT"`` for
        the JSON-lines stream (None: none).
    detector : detector of the automatic start and the recovery (``auto``, ``mediapipe``,
        ``classic``); hfov : field of view of the default camera (deg).
    recover : re-detect after lost frames (None: exactly when ``init_path`` is ``auto``).
    hand : ``"right"``, ``"left"`` or ``"auto"``: the side of the hand in the images; a
        left hand is tracked as the right hand of the mirror image
        (:mod:`digiteyes.camera.mirror`); ``"auto"`` takes the side the detector reports
        at the automatic start (right with a given start or a detector that cannot tell).
    max_side : images whose longer side exceeds this (px) are tracked resized to it
        (:mod:`digiteyes.camera.working_size`; None: never).
    check_every : with a learned detector on footage and a tracker other than the keypoint
        tracker, check the track against the detector every this many frames
        (:class:`~digiteyes.detect.check.DetectionCheck`; 0: never).
    init_frames : frames the automatic start may search for the hand before giving up
        (None: the whole input; a live camera waits until the hand shows).
    """

    inputs: tuple[str, ...]
    output: str
    model_name: str | None = None
    rig_path: str | None = None
    init_path: str | None = None
    iterations: int = 5
    window: float = 20.0
    links: str = "default"
    robust: str | None = None
    prediction: str = "none"
    shading: bool = True
    max_frames: int | None = None
    fps: float | None = None
    overlay: bool = True
    progress: bool = True
    tracker_name: str = AUTO_TRACKER
    options: tuple[tuple[str, object], ...] = ()
    strict: bool = False
    smooth: OneEuroOptions | None = None
    camera: int | None = None
    show: bool = False
    stream: str | None = None
    detector: str = "auto"
    hfov: float = DEFAULT_HFOV_DEG
    recover: bool | None = None
    init_frames: int | None = None
    hand: str = AUTO_HAND
    max_side: int | None = DEFAULT_MAX_SIDE
    check_every: int = DEFAULT_CHECK_EVERY


@dataclass
class _Source:
    """An opened input: frames, model, rig, the initial state (None: automatic), the
    frame rate, frame count when known, and the video lengths to check afterwards."""

    frames: Iterator[list[np.ndarray]]
    model: KinematicModel
    rig: Rig | None
    initial: np.ndarray | None
    rate: float
    total: int | None
    lengths: tuple[int, str | None] | None = None
    footage: bool = True


def _open_source(job: TrackJob) -> _Source:
    inputs = job.inputs
    auto = job.init_path == AUTO
    if job.camera is not None:
        if inputs:
            raise DatasetError("give either --camera or input files, not both")
        frames = open_capture_frames(job.camera)
        return _with_files(job, frames, None, frames.fps or DEFAULT_CAMERA_FPS, auto,
                           live=True)
    if not inputs:
        raise DatasetError("nothing to track: give a dataset folder, videos, folders of "
                           "images or --camera")
    if all(Path(p).is_dir() for p in inputs) and (
            len(inputs) > 1 or is_image_folder(inputs[0])):
        return _image_folders(job, auto)
    if len(inputs) == 1 and Path(inputs[0]).is_dir():
        dataset = open_sequence(inputs[0])
        model = load_model(job.model_name) if job.model_name else dataset.model
        rig = load_rig(job.rig_path) if job.rig_path else dataset.rig
        if auto:
            initial = None
        elif job.init_path:
            initial = State.load_json(model, job.init_path).q
        else:
            initial = State(model, dataset.initial_state).q
        return _Source(iter(dataset), model, rig, initial, job.fps or dataset.fps,
                       dataset.n_frames, footage=False)
    if any(Path(p).is_dir() for p in inputs):
        raise DatasetError("give one dataset folder, one video file per camera or one "
                           "folder of images per camera")
    lengths = check_lengths(list(inputs), job.strict)
    source = _with_files(job, open_video_frames(list(inputs)), None,
                         video_rate(list(inputs)), auto, live=False)
    source.lengths = lengths
    return source


def _image_folders(job: TrackJob, auto: bool) -> _Source:
    """Folders of still images, one per camera (:mod:`digiteyes.io.image_folder`), at
    ``--fps`` (default :data:`DEFAULT_FPS`: images carry no frame rate)."""
    frames, counts = open_image_folder_frames(list(job.inputs))
    lengths = check_lengths(list(job.inputs), job.strict, counts)
    source = _with_files(job, frames, min(counts), job.fps or DEFAULT_FPS, auto,
                         live=False)
    source.lengths = lengths
    return source


def video_rate(paths: list[str]) -> float:
    """The frame rate of the first video (:func:`~digiteyes.io.video.frame_rate`), or
    :data:`DEFAULT_FPS` when its container declares none; a warning on stderr when
    the videos of a rig declare different rates (the first camera's is used)."""
    rates = [frame_rate(p) for p in paths]
    known = [r for r in rates if r is not None]
    if len(known) > 1 and max(known) - min(known) > 1e-3 * max(known):
        listing = ", ".join(f"{p}: {r:g}" for p, r in zip(paths, rates, strict=True)
                            if r is not None)
        print(f"digiteyes track: warning: the videos declare different frame rates "
              f"({listing} frames/s); using the first", file=sys.stderr)
    return rates[0] if rates[0] is not None else DEFAULT_FPS


def _with_files(job: TrackJob, frames: Iterator[list[np.ndarray]], total: int | None,
                rate: float, auto: bool, live: bool) -> _Source:
    """Videos or a camera: model, rig and start from the job's files or defaults."""
    model = load_model(job.model_name or DEFAULT_MODEL)
    rig = load_rig(job.rig_path) if job.rig_path else None
    n_sources = 1 if live else len(job.inputs)
    if rig is None and n_sources != 1:
        raise CameraError(f"{n_sources} videos need a --rig (the default camera serves one)")
    if rig is not None and len(rig) != n_sources:
        raise CameraError(f"the rig has {len(rig)} camera(s) ({', '.join(rig.names)}) but "
                          f"{n_sources} {'camera' if live else 'video(s)'} were given")
    # footage without --init starts from the images (--init auto); before 27 Nov it was
    # an error, and a new user's first command failed
    auto = auto or not job.init_path
    initial = None if auto else State.load_json(model, job.init_path).q
    return _Source(frames, model, rig, initial, job.fps or rate, total)


def resolve_tracker(name: str, footage: bool, detector: str,
                    model: KinematicModel | None = None,
                    detector_agrees: Callable[[], bool] | None = None) -> str:
    """The tracker a job runs: ``name`` itself unless it is ``"auto"``. Then, for a hand
    model with the 21 hand keypoints (``model``; None: assume so) and a learned detector
    (MediaPipe installed and ``detector`` not ``"classic"``): on footage (videos,
    cameras) the keypoint tracker (:data:`FOOTAGE_TRACKER`); on a dataset, when
    ``detector_agrees()`` says that the detector takes its images for a hand where its
    initial state puts it (:func:`_detector_agrees`), the feature tracker anchored by the
    detector's keypoints (:data:`DATASET_TRACKER`; images a detector does not take for a
    hand, such as our own capsule drawing, keep the feature tracker). Otherwise the
    DigitEyes feature tracker (models of other objects or of part of a hand such as
    ``mouse-hand``, machines without the MediaPipe extra). Why: on the real video the
    feature tracker is more than half a palm length off MediaPipe's keypoints in 93 % of
    frames and flags 7, the keypoint tracker in none (docs/keypoint-tracker.md); on the
    flesh hand's renders the mean fingertip error over the accuracy table is 22.9 mm for
    the feature tracker, 16.2 for the keypoint tracker and 14.3 for the two joined
    (docs/anchored-features.md)."""
    if name != AUTO_TRACKER:
        return name
    from digiteyes.detect.mediapipe_detector import mediapipe_available

    learned = detector != "classic" and mediapipe_available()
    if not learned or (model is not None and not has_hand21(model)):
        return DEFAULT_TRACKER
    if footage:
        return FOOTAGE_TRACKER
    if detector_agrees is not None and detector_agrees():
        return DATASET_TRACKER
    return DEFAULT_TRACKER


def has_hand21(model: KinematicModel) -> bool:
    """Whether ``model`` has the 21 hand keypoints (:func:`~digiteyes.detect.hand21.
    model_anchors`): a full hand, not ``mouse-hand`` or ``two-finger``."""
    from digiteyes.detect.hand21 import model_anchors

    try:
        model_anchors(model)
    except DigitEyesError:
        return False
    return True


def job_tracker_options(job: TrackJob, model: KinematicModel, name: str,
                        footage: bool, auto: bool) -> dict[str, object]:
    """The options of tracker ``name``: the job's ``--option`` pairs over the flags.
    Trackers with a ``start_size`` option read the hand's size from a dataset's start
    (its true state), not from footage's, which the images gave (from the model's size)
    or the user placed by eye (``--init FILE``), nor from a start fitted to a dataset's
    images (``auto``; the keypoint tracker, which holds the palm where that fit put it,
    keeps reading it there); the model's (or a personal model's) size then stays
    (``--option start_size=true`` overrides)."""
    options = dict(job.options)
    if name == DATASET_TRACKER and job.detector in ("mediapipe", "mediapipe-lite"):
        options.setdefault("detector", job.detector)
    if name == FOOTAGE_TRACKER:
        options.setdefault("detector", job.detector)
        if footage:
            options.setdefault("start_size", False)
    elif (footage or auto) and "start_size" in {
            f.name for f in fields(tracker_entry(name).options_type)}:
        options.setdefault("start_size", False)
    if name == DEFAULT_TRACKER:
        flags = tracker_options(job.iterations, job.window, job.links, model, job.robust,
                                job.prediction, job.shading)
        options = {**vars(flags), **options}
    return options


def run_track_job(job: TrackJob, echo: Callable[[str], None] | None = None) -> TrackingRun:
    """Run ``job``: track its input and write every output into ``job.output``.

    ``echo`` receives one-line notes (the automatic start, a window that cannot be shown).
    Raises :class:`DatasetError` for a missing or empty input or when the automatic start
    finds no hand, :class:`CameraError` when the videos do not match the rig, and digiteyes
    errors naming the file for bad model, rig or state files.
    """
    say = echo or (lambda line: None)
    source = _open_source(job)
    frames = source.frames
    total = source.total
    if job.max_frames is not None:
        frames = islice(frames, job.max_frames)
        total = job.max_frames if total is None else min(total, job.max_frames)
    first = next(frames, None)
    if first is None:
        name = job.inputs[0] if job.inputs else f"camera {job.camera}"
        raise DatasetError(f"{name}: no frames to track")
    first = list(first)
    rig = source.rig or Rig((default_camera(first[0].shape[1], first[0].shape[0],
                                            job.hfov),))
    rig.check_images(first)
    frames = chain([first], frames)
    rig, frames = _transformed_input(job, rig, frames, say)
    model = nominal = source.model
    start_scale = 1.0
    auto = source.initial is None
    initialiser = None
    start_note: dict[str, object] = {"init": "auto" if auto else "given",
                                     "hand": "left" if rig.mirrored else "right"}
    if rig.real_sizes is not None:
        start_note["working_size"] = [rig[0].width, rig[0].height]
    if auto or job.recover:
        from digiteyes.detect.initialiser import AutoInitialiser

        # the side is known unless the images start the run and --hand auto leaves it
        # to the detector (then the start's hand decides it, below)
        side = None if auto and job.hand == AUTO_HAND else TRACKED_SIDE
        initialiser = AutoInitialiser(model, rig, job.detector, side=side)
        start_note["detector"] = initialiser.detector_class
    if auto:
        initial, skipped, frames = _search_start(initialiser, frames, job, total, say)
        start_note["first_frame"] = skipped
        start_note["found_by"] = sorted({c.detector for c in initialiser.last.candidates
                                         if c is not None})
        if total is not None:
            total -= skipped
        say(f"--init auto: hand found in frame {skipped} "
            f"({', '.join(start_note['found_by'])} + model fit)")
        seen = initialiser.last.sides(rig.mirrored)
        if job.hand == AUTO_HAND and seen == {"left"}:
            initialiser, rig, frames, initial = as_left_hand(initialiser, rig, frames,
                                                              initial)
            say("--hand auto: the detector sees a left hand; tracking it as the right hand "
                "of the mirror image (outputs in the real images)")
        elif job.hand != AUTO_HAND and seen and job.hand not in seen:
            say(f"warning: the detector sees a {' and a '.join(sorted(seen))} hand, the run "
                f"tracks a {job.hand} hand (--hand {sorted(seen)[0]} if that is the one)")
        initialiser.side = TRACKED_SIDE  # re-detections keep to the started hand's side
        start_note["hand"] = "left" if rig.mirrored else "right"
        initial, start_scale = initialiser.size_hand(initial)
        if start_scale != 1.0:  # two cameras measured the hand: track a model of its size
            model = initialiser.model
            start_note["two_camera_hand_scale"] = start_scale
            say(f"--init auto: the cameras measure the hand {start_scale:.3f} times the "
                "model's size; tracking a model of that size")
    else:
        initial = np.asarray(source.initial)
    first_index = int(start_note.get("first_frame", 0))
    recover = initialiser if (job.recover if job.recover is not None else auto) else None
    ahead = [next(frames)]  # frames read ahead by the choice of tracker, tracked after
    rest = frames

    def agrees() -> bool:
        ahead.extend(islice(rest, AGREEMENT_FRAMES - 1))
        return _detector_agrees(model, rig, job.detector, ahead, initial)

    name = resolve_tracker(job.tracker_name, source.footage, job.detector, model, agrees)
    frames = chain(ahead, rest)
    if name != job.tracker_name:
        say(f"tracker: {name} (--tracker auto: "
            f"{_why_tracker(name, source.footage, job.detector, model)})")
    tracker = create_tracker(name, model, rig,
                             **job_tracker_options(job, model, name, source.footage, auto))
    check = _detection_check(job, source.footage, tracker, model, rig)
    out = Path(job.output)
    out.mkdir(parents=True, exist_ok=True)
    sinks = _open_sinks(job, model, rig, out, source.rate, say)
    try:
        run = run_tracker(tracker, model, rig, frames, initial, out, fps=source.rate,
                          total=total, overlay=job.overlay, progress=job.progress,
                          tracker_name=name, recover=recover, sinks=sinks,
                          first_index=first_index, check=check)
    finally:
        for sink in sinks:
            sink.close()
    run.files["keypoints"] = out / KEYPOINTS_FILE
    segments, tracker_scale = None, 1.0
    if sizes_hand(tracker):
        start_note["hand_scale"] = start_scale * float(getattr(tracker, "start_scale",
                                                               tracker.scale))
        segments = getattr(tracker, "measured_segments", None)
        tracker_scale = 1.0 if run.hand_scale is None else run.hand_scale
    if start_scale * tracker_scale != 1.0 or segments is not None:
        run.files["measured-model"] = _write_measured_model(
            nominal, start_scale * tracker_scale, segments, out, say)
    _record_start(run, start_note, initialiser, job.smooth, source.rate, check)
    if source.lengths is not None and not run.interrupted and job.max_frames is None:
        record_missing(run.files["summary"], source.lengths[0], first_index + run.n_frames,
                       source.lengths[1])
    run.files.update(write_track_extras(out, model, source.rate, job.smooth))
    run.files["model"] = write_track_model(out, model)
    from digiteyes.evaluate.report_page import write_report_page

    run.files["report"] = write_report_page(out)
    return run


MEASURED_MODEL = "hand-measured.dh"
"""The model file ``track`` writes when the tracker measured the hand's size."""


def _write_measured_model(model: KinematicModel, scale: float,
                          segments: np.ndarray | None, out: Path,
                          say: Callable[[str], None]) -> Path:
    """Write ``model`` (the model file's) at the size measured, ``scale``: the two cameras'
    at the automatic start (:meth:`~digiteyes.detect.initialiser.AutoInitialiser.size_hand`)
    times the tracker's at its last frame, with the 15 finger ``segments`` (mm) when the
    tracker measured them, as ``out/hand-measured.dh``, to track later footage of the same
    hand with ``--model`` (one camera cannot measure the size itself); say so."""
    from digiteyes.detect.hand_size import model_hand_length, write_personal_model

    path = out / MEASURED_MODEL
    personal = write_personal_model(model, scale, path, name=model.name, lengths=segments,
                                    source="digiteyes track (the size it measured)")
    measured = ", and its 15 finger segments" if segments is not None else ""
    say(f"the hand measured {scale:.3f} times the model's size (hand length "
        f"{model_hand_length(personal):.0f} mm{measured}): {path} (track it with --model "
        f"{path})")
    return path


def _transformed_input(job: TrackJob, rig: Rig, frames: Iterator[list[np.ndarray]],
                       say: Callable[[str], None]) -> tuple[Rig, Iterator[list[np.ndarray]]]:
    """The rig and frames the tracker sees: resized to the working size
    (:mod:`digiteyes.camera.working_size`), then mirrored for ``--hand left``
    (:mod:`digiteyes.camera.mirror`; ``auto`` decides at the automatic start)."""
    work = working_rig(rig, job.max_side)
    if work is not rig:
        say(f"tracking at {work[0].width}x{work[0].height} (images {rig[0].width}x"
            f"{rig[0].height}, --max-size {job.max_side}); outputs in the images' pixels")
        frames = (resize_images(images, work) for images in frames)
        rig = work
    if job.hand == "left":
        rig = mirrored_rig(rig)
        frames = (mirror_images(images) for images in frames)
    return rig, frames


def _why_tracker(name: str, footage: bool, detector: str, model: KinematicModel) -> str:
    """Why ``--tracker auto`` chose ``name`` (:func:`resolve_tracker`), for the log; on
    footage without the MediaPipe extra, what it costs and how to install it."""
    if name == FOOTAGE_TRACKER:
        return "footage with a learned detector"
    if name == DATASET_TRACKER:
        return ("a dataset whose hand the detector finds where its start is: the feature "
                "tracker with the detector's keypoints")
    if not footage:
        return "a dataset"
    if not has_hand21(model):
        return "a model without the 21 hand keypoints"
    if detector == "classic":
        return "--detector classic"
    return ('MediaPipe is not installed. On real footage the feature tracker drifts off '
            'the hand within frames, the keypoint tracker stays on it '
            '(docs/keypoint-tracker.md): pip install "digiteyes[mediapipe]"')


def _search_start(initialiser: AutoInitialiser, frames: Iterator[list[np.ndarray]],
                  job: TrackJob, total: int | None, say: Callable[[str], None],
                  ) -> tuple[np.ndarray, int, Iterator[list[np.ndarray]]]:
    """The automatic start: search the input for the first frame with a hand (a bar while
    the search lasts more than the first frame)."""
    from digiteyes.detect.initialiser import start_automatically

    bar = None
    other = {"left": "right", "right": "left"}.get(job.hand)
    hint = (f"; the detector sees a {other} hand, and --hand {job.hand} was asked for "
            f"(--hand {other}, or auto to take the side it sees)") if other else ""
    other_seen = False

    def searched(index: int) -> None:
        nonlocal bar, other_seen
        if not other_seen and initialiser.last is not None and initialiser.last.other_hands:
            other_seen = True  # said once: why a visible hand does not start the run
            say(f"--init auto: no {job.hand} hand in frame {index}{hint}")
        if bar is None:
            if job.camera is not None:
                say("--init auto: waiting for a hand in view")
            elif not other_seen:
                say("--init auto: no hand in frame 0; searching the following frames")
            bar = tqdm(total=total, initial=1, unit="frame", desc="looking for a hand",
                       disable=not job.progress)
        else:
            bar.update()

    try:
        return start_automatically(initialiser, frames, job.init_frames, searched)
    except DatasetError as error:
        raise DatasetError(f"{error}{hint if other_seen else ''}") from None
    finally:
        if bar is not None:
            bar.close()


def _open_sinks(job: TrackJob, model: KinematicModel, rig: Rig, out: Path, fps: float,
                say: Callable[[str], None]) -> list[FrameSink]:
    """``keypoints.csv`` always; the stream (smoothed too with ``job.smooth``, at ``fps``)
    and the window when asked for."""
    keypoints = CameraKeypoints(model, rig)  # one frame's keypoints, for every sink
    sinks: list[FrameSink] = [KeypointLog(out / KEYPOINTS_FILE, keypoints)]
    try:
        if job.stream is not None:
            sinks.append(JsonLinesStream(job.stream, keypoints, smooth=job.smooth, fps=fps))
        if job.show:
            from digiteyes.viz.live_window import open_live_window

            window, note = open_live_window(model, rig)
            say(note)
            if window is not None:
                sinks.append(window)
    except BaseException:
        for sink in sinks:
            sink.close()
        raise
    return sinks


AGREEMENT_FRAMES = 20
"""The dataset's first frames in which the detector must find a hand ..."""
AGREEMENT_RATE = 0.9
"""... in at least this fraction (first camera) for the keypoint tracker to be chosen."""


def _detector_agrees(model: KinematicModel, rig: Rig, detector: str,
                     frames: list[list[np.ndarray]], state: np.ndarray) -> bool:
    """Whether the detector takes a dataset's images for a hand: on the first of
    ``frames`` no digit of the initial ``state`` off the detected hand (the detection
    check's bound, ``DetectionCheck.max_gap``: half a palm length), and a hand found in
    at least :data:`AGREEMENT_RATE` of them (the first camera's images).
    Both are needed: the first frame alone passes our capsule drawing of the desk view
    (the thumb's gap 0.21 palm lengths), in whose first 40 grey frames MediaPipe finds a
    hand in 40 % (16; the flesh hand: 100 %; measured with grey images tinted to skin,
    :func:`~digiteyes.detect.mediapipe_detector.skin_tinted`); and the gap's old bound of
    0.25 refused a flesh hand 0.9 times the model's size (0.26, the thumb: MediaPipe's
    thumb base is not the model's). Not caught: our drawing of the egocentric view, a
    hand to MediaPipe in 37 of its first 40 tinted frames."""
    from digiteyes.detect.check import DetectionCheck
    from digiteyes.detect.pose import make_detector

    check = DetectionCheck(model, rig, detector)
    worst = check.worst_digit(frames[0], state)
    if worst is None or worst[0] > check.max_gap:
        return False
    still = make_detector(detector, model, look_turned=False)  # frames, as the start's
    found = sum(bool(still.detect(images[0], rig[0])) for images in frames)
    getattr(still, "close", lambda: None)()
    return found >= AGREEMENT_RATE * len(frames)


def _detection_check(job: TrackJob, footage: bool, tracker: Tracker, model: KinematicModel,
                     rig: Rig) -> DetectionCheck | None:
    """The detector's check of the track (:mod:`digiteyes.detect.check`): on footage,
    with a learned detector, for every tracker but those that run the detector on every
    frame themselves (``follows_detector``: the keypoint tracker, ``features+keypoints``)
    and every model with the 21 hand keypoints."""
    from digiteyes.detect.check import DetectionCheck
    from digiteyes.detect.mediapipe_detector import mediapipe_available

    if (not footage or job.check_every <= 0 or getattr(tracker, "follows_detector", False)
            or job.detector == "classic" or not mediapipe_available()):
        return None
    if not has_hand21(model):  # another object, or part of a hand
        return None
    return DetectionCheck(model, rig, job.detector, job.check_every)


def as_left_hand(initialiser: AutoInitialiser, rig: Rig, frames: Iterator[list[np.ndarray]],
                 state: np.ndarray) -> tuple[AutoInitialiser, Rig, Iterator, np.ndarray]:
    """Switch a started run to the mirror image (``--hand auto`` and a left hand): the
    mirrored rig, the mirrored frames, an initialiser for them and the state fitted to the
    mirrored start frame (``state`` kept if that fit fails)."""
    from digiteyes.detect.initialiser import AutoInitialiser

    mirrored = mirrored_rig(rig)
    first = next(frames)
    fresh = AutoInitialiser(initialiser.model, mirrored, initialiser.detector,
                            side=TRACKED_SIDE)
    fitted = fresh(mirror_images(first))
    if fitted is None:
        return initialiser, rig, chain([first], frames), state
    flipped = (mirror_images(images) for images in frames)
    return fresh, mirrored, chain([mirror_images(first)], flipped), fitted


def _record_start(run: TrackingRun, note: dict[str, object], initialiser,
                  smooth: OneEuroOptions | None, fps: float,
                  check: DetectionCheck | None = None) -> None:
    """Add how the run started, the detector's work, the detector's checks and, with
    ``smooth``, the settings of the smoothed outputs to ``summary.json``."""
    path = run.files["summary"]
    summary = read_json_object(path, DatasetError, "summary file")
    if initialiser is not None:
        note.update(detections_tried=initialiser.calls, detections_found=initialiser.found,
                    detection_seconds=initialiser.seconds)
    summary["start"] = note
    if check is not None:
        summary["detection_check"] = check.to_json()
    if smooth is not None:
        summary["smoothing"] = {"filter": "One Euro, one cutoff (docs/output.md)",
                                "fps": fps, **vars(smooth)}
    atomic_write_json(path, summary)
