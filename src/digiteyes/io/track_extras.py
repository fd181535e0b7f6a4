"""What ``digiteyes track`` writes after tracking, from the state log: joint angles,
the One Euro-filtered states, the report page; and how a track folder is read back for
``digiteyes export`` (its model and its states, raw or filtered)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from digiteyes.errors import DatasetError, DigitEyesError
from digiteyes.filters import OneEuroOptions, one_euro_filter, restarts_after_losses
from digiteyes.io.safe_paths import atomic_write_bytes
from digiteyes.io.state_log import (
    LOG_COLUMNS,
    OPTIONAL_COLUMNS,
    StateLog,
    StateLogWriter,
    read_state_log,
)
from digiteyes.io.video import DEFAULT_FPS
from digiteyes.kinematics import KinematicModel, format_model_text, load_model, model_from_file
from digiteyes.kinematics.joint_angles import write_joint_angles_csv
from digiteyes.models import shipped_models

STATES = "states.csv"
TRACK_MODEL = "model.dh"
SMOOTHED_STATES = "states-smoothed.csv"
JOINT_ANGLES = "joint_angles.csv"
SMOOTHED_JOINT_ANGLES = "joint_angles-smoothed.csv"


def smooth_log(log: StateLog, model: KinematicModel, fps: float,
               options: OneEuroOptions | None = None) -> StateLog:
    """The log with its states One Euro-filtered (restarting after each lost frame)."""
    states = one_euro_filter(model, log.states, fps, options,
                             reset=restarts_after_losses(log.lost))
    return StateLog(log.frames, states, log.lost, log.residual_rms_px, log.iterations,
                    log.time_s, log.hand_scale)


def write_log(path: Path, log: StateLog, model: KinematicModel) -> Path:
    """Write ``log`` as a state log (the format of ``states.csv``; with its
    ``hand_scale`` column when the hand is not the model's size)."""
    sized = bool(np.any(log.hand_scale != 1.0))
    with StateLogWriter(path, model, hand_scale=sized) as writer:
        for i in range(len(log)):
            writer.append(int(log.frames[i]), log.states[i], time_s=float(log.time_s[i]),
                          lost=bool(log.lost[i]),
                          residual_rms_px=float(log.residual_rms_px[i]),
                          iterations=int(log.iterations[i]),
                          hand_scale=float(log.hand_scale[i]))
    return path


def write_track_extras(out_dir: str | Path, model: KinematicModel, fps: float,
                       smooth: OneEuroOptions | None = None) -> dict[str, Path]:
    """From ``out_dir/states.csv``: ``joint_angles.csv`` and, with ``smooth``,
    ``states-smoothed.csv`` and ``joint_angles-smoothed.csv``; return the files by key."""
    out = Path(out_dir)
    log = read_state_log(out / STATES, model)
    files = {"joint-angles": write_joint_angles_csv(out / JOINT_ANGLES, model, log.frames,
                                                    log.states)}
    if smooth is not None and len(log):
        smoothed = smooth_log(log, model, fps, smooth)
        files["states-smoothed"] = write_log(out / SMOOTHED_STATES, smoothed, model)
        files["joint-angles-smoothed"] = write_joint_angles_csv(
            out / SMOOTHED_JOINT_ANGLES, model, smoothed.frames, smoothed.states)
    return files


def write_track_model(out_dir: str | Path, model: KinematicModel) -> Path:
    """Write the model a run tracked with as ``out_dir/model.dh`` (atomically), so that
    what reads the folder later (``export``, ``mouse --replay``) draws the states with
    the same hand, a personal model's lengths included (:func:`model_of_log`)."""
    path = Path(out_dir) / TRACK_MODEL
    text = (f"# the model digiteyes track ran with ({model.name}); export and replay read "
            f"it\n{format_model_text(model.spec)}")
    atomic_write_bytes(path, text.encode("utf-8"))
    return path


def model_of_log(path: str | Path) -> KinematicModel:
    """The model a state log was tracked with: the ``model.dh`` that ``track`` writes
    beside it (:func:`write_track_model`), else the shipped model whose state names are
    exactly the log's state columns. Raises
    :class:`DatasetError` when none or several shipped models fit (then pass
    ``--model``), or when the folder's ``model.dh`` cannot be read."""
    path = Path(path)
    beside = path.parent / TRACK_MODEL
    if beside.is_file():
        try:
            model = model_from_file(beside)
        except DigitEyesError as exc:
            raise DatasetError(f"{beside}: {exc}") from None
        return model
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            header = next(csv.reader(handle), [])
    except OSError as exc:
        raise DatasetError(f"{path}: cannot read state log ({exc.strerror or exc})") from None
    names = tuple(h for h in header if h not in LOG_COLUMNS + OPTIONAL_COLUMNS)
    fits = [m for m in shipped_models() if load_model(m).state_names == names]
    if len(fits) != 1:
        raise DatasetError(f"{path}: cannot tell the model from the header "
                           f"({'several' if fits else 'no'} shipped model(s) fit); give --model")
    return load_model(fits[0])


def _summary(track_dir: str | Path) -> dict:
    """A track folder's ``summary.json`` ({} when there is none)."""
    path = Path(track_dir) / "summary.json"
    if not path.is_file():
        return {}
    try:
        summary = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise DatasetError(f"{path}: cannot read ({exc})") from None
    if not isinstance(summary, dict):
        raise DatasetError(f"{path}: expected a JSON object")
    return summary


def track_fps(track_dir: str | Path) -> float | None:
    """The frame rate recorded in ``summary.json`` (key ``fps``), or None."""
    value = _summary(track_dir).get("fps")
    return float(value) if isinstance(value, int | float) and value > 0 else None


def track_is_left_hand(track_dir: str | Path) -> bool:
    """Whether ``summary.json`` says the run tracked a left hand (``start.hand``; its
    states are those of the mirror image's right hand, :mod:`digiteyes.camera.mirror`)."""
    start = _summary(track_dir).get("start")
    return isinstance(start, dict) and start.get("hand") == "left"


def track_residual_unit(track_dir: str | Path) -> str:
    """The unit of the state log's ``residual_rms_px`` column recorded in ``summary.json``
    (key ``residual_unit``: ``"px"``, or ``"grey level"`` for the template trackers);
    ``"px"`` when the folder does not say."""
    value = _summary(track_dir).get("residual_unit")
    return value if isinstance(value, str) and value else "px"


def read_track(track_dir: str | Path, model: KinematicModel | None, fps: float | None,
               smooth: OneEuroOptions | None) -> tuple[KinematicModel, StateLog, float]:
    """Model, state log (filtered when ``smooth``) and frame rate of a track folder (or a
    state-log file). ``fps`` None: the folder's ``summary.json``, else 10."""
    track_dir = Path(track_dir)
    log_path = track_dir if track_dir.is_file() else track_dir / STATES
    if not log_path.is_file():
        raise DigitEyesError(f"{track_dir}: no {STATES} (not a track folder)")
    model = model or model_of_log(log_path)
    fps = fps or track_fps(log_path.parent) or DEFAULT_FPS
    log = read_state_log(log_path, model)
    if smooth is not None:
        log = smooth_log(log, model, fps, smooth)
    return model, log, fps
