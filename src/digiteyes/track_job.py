"""One tracking job: an input (a dataset folder, or one video per camera), the settings of
``digiteyes track``, and the function that runs it (:func:`run_track_job`).

``digiteyes track`` runs one job; ``digiteyes track-many`` (:mod:`digiteyes.track_many`)
runs one per input, each as a Ray task. Both call :func:`run_track_job`, which opens the
input, builds the :class:`~digiteyes.trackers.FeatureTracker` and hands the frames to
:func:`digiteyes.pipeline.run_tracker` (the outputs are listed there).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import chain, islice
from pathlib import Path

import numpy as np

from digiteyes.camera import load_rig
from digiteyes.errors import CameraError, DatasetError
from digiteyes.features import FeatureOptions
from digiteyes.io import open_sequence, open_video_frames
from digiteyes.kinematics import KinematicModel, State, load_model
from digiteyes.pipeline import TrackingRun, run_tracker
from digiteyes.trackers import (
    FeatureTracker,
    FeatureTrackerOptions,
    all_features,
    thesis_whole_hand_links,
)


def tracker_options(iterations: int, window: float, links: str, model: KinematicModel,
                    robust: str | None, prediction: str, shading: bool = True
                    ) -> FeatureTrackerOptions:
    """Tracker settings from the command-line choices (shared with ``digiteyes demo``).

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
    inputs : one dataset folder, or one video file per camera of the rig, in rig order.
    output : output folder.
    model_name, rig_path, init_path : override the dataset's model, rig and initial state
        (all three required for videos).
    iterations : Gauss-Newton iterations per frame; window : search window, px; links,
        robust, prediction, shading : as :func:`tracker_options`.
    max_frames : track at most this many frames (None: all).
    fps : overlay video frame rate (None: the dataset's, or 10).
    overlay : write the overlay video; progress : show a progress bar.
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


def run_track_job(job: TrackJob) -> TrackingRun:
    """Open ``job.inputs``, track them with the feature tracker and write the outputs of
    :func:`digiteyes.pipeline.run_tracker` into ``job.output``.

    Raises :class:`DatasetError` for a missing or empty input, :class:`CameraError` when
    the videos do not match the rig, and ``ValueError``-style digiteyes errors for bad
    model, rig or state files (each naming the file).
    """
    inputs = job.inputs
    dataset = None
    if len(inputs) == 1 and Path(inputs[0]).is_dir():
        dataset = open_sequence(inputs[0])
    elif any(Path(p).is_dir() for p in inputs):
        raise DatasetError("give one dataset folder, or one video file per camera")
    if dataset is None and not (job.model_name and job.rig_path and job.init_path):
        raise DatasetError(f"{inputs[0]}: tracking videos needs --model, --rig and --init")
    model = load_model(job.model_name) if job.model_name else dataset.model
    rig = load_rig(job.rig_path) if job.rig_path else dataset.rig
    if job.init_path:
        initial = State.load_json(model, job.init_path).q
    else:
        initial = State(model, dataset.initial_state).q
    if dataset is not None:
        frames = iter(dataset)
        total = dataset.n_frames
        rate = job.fps or dataset.fps
    else:
        if len(inputs) != len(rig):
            raise CameraError(f"the rig has {len(rig)} camera(s) ({', '.join(rig.names)}) but "
                              f"{len(inputs)} video(s) were given")
        frames = open_video_frames(list(inputs))
        total = None
        rate = job.fps or 10.0
    if job.max_frames is not None:
        frames = islice(frames, job.max_frames)
        total = job.max_frames if total is None else min(total, job.max_frames)
    first = next(frames, None)
    if first is None:
        raise DatasetError(f"{inputs[0]}: no frames to track")
    rig.check_images(first)
    options = tracker_options(job.iterations, job.window, job.links, model, job.robust,
                              job.prediction, job.shading)
    tracker = FeatureTracker(model, rig, options)
    return run_tracker(tracker, model, rig, chain([first], frames), np.asarray(initial),
                       job.output, fps=rate, total=total, overlay=job.overlay,
                       progress=job.progress)
