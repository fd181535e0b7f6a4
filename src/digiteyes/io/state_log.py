"""State logs: the CSV every tracker run writes, one row per frame (DESIGN §5, thesis §4.3.3).

The thesis logged the estimated states of its real-time runs and plotted them afterwards
(Figs. 4.7, 4.8); ``digiteyes evaluate`` reads the same log. Header::

    frame,time_s,lost,residual_rms_px,iterations[,reinitialised][,hand_scale],<state names>

``frame`` is the 0-based index of the frame in its sequence or video, ``time_s`` the
wall-clock seconds spent on that frame (measurement + solving), ``lost`` 0 or 1 (the
tracker's own track-loss flag), ``residual_rms_px`` the RMS image residual after the last
iteration (pixels; empty cell or ``nan`` when unknown), ``iterations`` the solver iterations
spent on the frame, the optional columns of :data:`OPTIONAL_COLUMNS`, then the estimated
state (mm, radians, quaternion w, x, y, z). Every row
is flushed as soon as it is written, so an interrupted run keeps every frame it finished.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from digiteyes.errors import DatasetError, StateError
from digiteyes.kinematics import KinematicModel, validate_state

LOG_COLUMNS = ("frame", "time_s", "lost", "residual_rms_px", "iterations")
OPTIONAL_COLUMNS = ("reinitialised", "hand_scale")
"""Columns a log may carry after :data:`LOG_COLUMNS`, in this order: ``reinitialised``
(0 or 1) is written when the run re-detects after a loss (``digiteyes track --init
auto``); 1 marks a frame whose state came from the detector and the model fit.
``hand_scale`` is written by trackers that fit the hand's size (the keypoint tracker):
the size of the hand the row's state poses, relative to the model file
(:attr:`~digiteyes.trackers.TrackResult.hand_scale`); without the column it is 1."""


@dataclass(frozen=True)
class StateLog:
    """A state log read back: T rows.

    frames (T,) int, states (T, n_q), lost (T,) bool, residual_rms_px (T,) px (nan when
    unknown), iterations (T,) int, time_s (T,) seconds per frame, hand_scale (T,) the
    hand's size relative to the model file (ones when the log has no such column).
    """

    frames: np.ndarray
    states: np.ndarray
    lost: np.ndarray
    residual_rms_px: np.ndarray
    iterations: np.ndarray
    time_s: np.ndarray
    hand_scale: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.hand_scale is None:
            object.__setattr__(self, "hand_scale", np.ones(len(self.frames)))

    def __len__(self) -> int:
        return len(self.frames)

    @property
    def median_hand_scale(self) -> float:
        """The hand's size over the log (median of ``hand_scale``; 1 for an empty log):
        what a whole-track output (an export, a replay) draws the states at."""
        return float(np.median(self.hand_scale)) if len(self) else 1.0


class StateLogWriter:
    """Append tracker results to a state-log CSV (context manager).

    Creates the parent folder; replaces an existing file. Each row is flushed to the
    operating system at once. OSError (unwritable folder, full disk) becomes
    :class:`DatasetError` naming the file.
    """

    def __init__(self, path: str | Path, model: KinematicModel, *,
                 reinitialised: bool = False, hand_scale: bool = False) -> None:
        self.path = Path(path)
        self.model = model
        self.reinitialised = reinitialised
        self.hand_scale = hand_scale
        self.n_rows = 0
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._handle = open(self.path, "w", newline="", encoding="utf-8")
        except OSError as exc:
            raise DatasetError(f"{self.path}: cannot create state log ({exc.strerror or exc})"
                               ) from None
        self._buffer = io.StringIO()
        self._writer = csv.writer(self._buffer)
        optional = [c for c, on in zip(OPTIONAL_COLUMNS, (reinitialised, hand_scale),
                                       strict=True) if on]
        self._write([*LOG_COLUMNS, *optional, *model.state_names])

    def _write(self, row: list[str]) -> None:
        try:
            self._buffer.seek(0)
            self._buffer.truncate()
            self._writer.writerow(row)
            self._handle.write(self._buffer.getvalue())
            self._handle.flush()
        except OSError as exc:
            raise DatasetError(f"{self.path}: cannot write state log ({exc.strerror or exc})"
                               ) from None

    def append(self, frame: int, state: np.ndarray, *, time_s: float, lost: bool,
               residual_rms_px: float, iterations: int, reinitialised: bool = False,
               hand_scale: float = 1.0) -> None:
        """Write one row: the estimate of ``frame`` (0-based) and how it was obtained
        (``reinitialised`` and ``hand_scale`` are written only by a writer created with
        that column)."""
        if self._handle.closed:
            raise DatasetError(f"{self.path}: state log is closed")
        state = np.asarray(state, dtype=float)
        if state.shape != (self.model.n_q,):
            raise StateError(f"model {self.model.name!r} needs states of size "
                             f"{self.model.n_q}, got shape {state.shape}")
        self._write([str(int(frame)), repr(float(time_s)), str(int(bool(lost))),
                     repr(float(residual_rms_px)), str(int(iterations)),
                     *([str(int(bool(reinitialised)))] if self.reinitialised else []),
                     *([repr(float(hand_scale))] if self.hand_scale else []),
                     *(repr(float(x)) for x in state)])
        self.n_rows += 1

    def close(self) -> None:
        """Close the file (idempotent)."""
        self._handle.close()

    def __enter__(self) -> StateLogWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _number(text: str, path: Path, line: int, column: str, integer: bool = False) -> float:
    if column == "residual_rms_px" and text.strip() == "":
        return math.nan
    try:
        value = float(text)
        if integer:
            if not value.is_integer():
                raise ValueError(text)
            return int(value)
        return value
    except ValueError:
        kind = "an integer" if integer else "a number"
        raise DatasetError(f"{path}:{line}: column {column!r} must be {kind}, got {text!r}"
                           ) from None


def read_state_log(path: str | Path, model: KinematicModel) -> StateLog:
    """Read a state log written by :class:`StateLogWriter` for ``model``.

    Every complete row ends with a line break (the writer writes each row in one piece);
    a last row without one was cut short (interruption, full disk) and is dropped, even
    when its cells look whole (``0.1304010223817`` cut from ``0.13040102238174398``).
    Raises :class:`DatasetError` naming the file (and line) for a missing file, a header
    without the log columns or without the model's state names (a log of another model),
    or unreadable values.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise DatasetError(f"{path}: no such state log") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DatasetError(f"{path}: cannot read state log ({exc})") from None
    try:
        rows = list(csv.reader(text.splitlines()))
    except csv.Error as exc:
        raise DatasetError(f"{path}: not a readable state log ({exc})") from None
    if not rows:
        raise DatasetError(f"{path}: empty; expected a header "
                           f"{','.join(LOG_COLUMNS)},<state names>")
    header = rows[0]
    missing = [c for c in LOG_COLUMNS if c not in header]
    if missing:
        raise DatasetError(f"{path}: not a state log; header lacks {', '.join(missing)}")
    missing = [n for n in model.state_names if n not in header]
    if missing:
        raise DatasetError(f"{path}: not a log of model {model.name!r}: header lacks states "
                           f"{', '.join(missing)}")
    body = rows[1:]
    if body and not text.endswith("\n"):
        body = body[:-1]  # unterminated: cut by an interruption or a full disk
    col = {name: header.index(name) for name in (*LOG_COLUMNS, *model.state_names)}
    n = len(body)
    frames = np.empty(n, dtype=int)
    iterations = np.empty(n, dtype=int)
    lost = np.empty(n, dtype=bool)
    residual = np.empty(n)
    time_s = np.empty(n)
    hand_scale = np.ones(n)
    scale_column = header.index("hand_scale") if "hand_scale" in header else None
    states = np.empty((n, model.n_q))
    for i, row in enumerate(body):
        line = i + 2
        if len(row) != len(header):
            raise DatasetError(f"{path}:{line}: expected {len(header)} cells, got {len(row)}")
        frames[i] = _number(row[col["frame"]], path, line, "frame", integer=True)
        iterations[i] = _number(row[col["iterations"]], path, line, "iterations", integer=True)
        lost[i] = _number(row[col["lost"]], path, line, "lost", integer=True) != 0
        residual[i] = _number(row[col["residual_rms_px"]], path, line, "residual_rms_px")
        time_s[i] = _number(row[col["time_s"]], path, line, "time_s")
        if scale_column is not None:
            hand_scale[i] = _number(row[scale_column], path, line, "hand_scale")
            if not hand_scale[i] > 0:
                raise DatasetError(f"{path}:{line}: column 'hand_scale' must be positive, "
                                   f"got {row[scale_column]!r}")
        states[i] = [_number(row[col[name]], path, line, name) for name in model.state_names]
    try:
        validate_state(model, states, normalize=True)
    except StateError as exc:
        raise DatasetError(f"{path}: {exc}") from None
    return StateLog(frames, states, lost, residual, iterations, time_s, hand_scale)
