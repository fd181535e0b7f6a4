"""Sequence folders on disk: frames, rig, model, initial state and ground truth (DESIGN §6).

The format is specified in docs/dataset.md. A folder ``SEQ/`` holds::

    sequence.json        what is where, how many frames are complete
    model.dh             the model file text used
    rig.json             the camera rig (digiteyes.camera.save_rig)
    initial_state.json   State.save_json
    cam0/000000.png ...  frames, one folder per camera (or one video file per camera)
    truth/states.csv     true state per frame (column "frame" first)
    truth/keypoints.npz  names (K,), keypoints_3d (T,K,3) mm, keypoints_2d (T,C,K,2) px,
                         visible (T,C,K)

:class:`SequenceWriter` writes it crash-safely (atomic file replaces, ``sequence.json``
counting only complete frames, periodic checkpoints, ``resume``); :func:`open_sequence`
reads and checks it. Images are ``uint8`` (or ``uint16`` for PNG) arrays, ``(H, W)`` grey or
``(H, W, 3)`` RGB (red first).
"""

from __future__ import annotations

import contextlib
import json
import os
import zipfile
import zlib
from collections.abc import Callable, Iterator
from collections.abc import Sequence as SequenceABC
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from digiteyes.camera import Rig, load_rig, save_rig
from digiteyes.errors import DatasetError, StateError
from digiteyes.io.safe_paths import check_name, inside
from digiteyes.io.video import (
    DEFAULT_H264_CRF,
    VIDEO_CODECS,
    VideoReader,
    VideoWriter,
    checked_crf,
)
from digiteyes.jsonfile import read_json_object
from digiteyes.kinematics import (
    KinematicModel,
    State,
    load_model,
    read_states_csv,
    write_states_csv,
)
from digiteyes.version import __version__

FORMAT = "digiteyes-sequence"
VERSION = 1
PNG_PATTERN = "{camera}/{index:06d}.png"
SEQUENCE_FILE = "sequence.json"
MODEL_FILE = "model.dh"
RIG_FILE = "rig.json"
INITIAL_STATE_FILE = "initial_state.json"
TRUTH_STATES = "truth/states.csv"
TRUTH_KEYPOINTS = "truth/keypoints.npz"
CHECKPOINT_EVERY = 25


@dataclass(frozen=True)
class FrameTruth:
    """Ground truth of one frame.

    state : (n_q,) true state. keypoint_names : K names. keypoints_3d : (K, 3) world mm.
    keypoints_2d : (C, K, 2) pixels per camera of the rig. visible : (C, K) bool, keypoint
    seen by that camera (not occluded, inside the image).
    """

    state: np.ndarray
    keypoint_names: tuple[str, ...]
    keypoints_3d: np.ndarray
    keypoints_2d: np.ndarray
    visible: np.ndarray


@dataclass(frozen=True)
class GroundTruth:
    """Ground truth of a whole sequence (T frames, C cameras, K keypoints).

    states : (T, n_q), or None when only keypoints are known (e.g. markers measured by
    stereo, thesis §4.1). keypoint_names : K names (K may be 0 when only states are known).
    keypoints_3d : (T, K, 3) world mm. keypoints_2d : (T, C, K, 2) px. visible : (T, C, K).
    """

    states: np.ndarray | None
    keypoint_names: tuple[str, ...]
    keypoints_3d: np.ndarray
    keypoints_2d: np.ndarray
    visible: np.ndarray

    def __len__(self) -> int:
        return len(self.keypoints_3d) if self.states is None else len(self.states)


# --------------------------------------------------------------------------- file helpers
def _atomic_write(path: Path, data: bytes) -> None:
    """Write ``data`` to a temporary name beside ``path``, then rename it over ``path``."""
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        with open(tmp, "wb") as handle:
            handle.write(data)
        os.replace(tmp, path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        raise DatasetError(f"{path}: cannot write ({exc.strerror or exc})") from None


def _encode_png(image: np.ndarray, where: str) -> bytes:
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
    ok, buffer = cv2.imencode(".png", image)
    if not ok:
        raise DatasetError(f"{where}: PNG encoding failed")
    return buffer.tobytes()


def read_png(path: str | Path) -> np.ndarray:
    """Read a PNG (or any image OpenCV reads): (H, W) grey or (H, W, 3) RGB, dtype kept.

    Alpha channels are dropped. Raises :class:`DatasetError` if the file is missing or
    unreadable.
    """
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: missing image file")
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise DatasetError(f"{path}: not a readable image")
    if image.ndim == 3:
        code = cv2.COLOR_BGRA2RGB if image.shape[2] == 4 else cv2.COLOR_BGR2RGB
        image = cv2.cvtColor(image, code)
    return image


def _check_image(image: np.ndarray, rig: Rig, c: int, where: str, video: bool) -> np.ndarray:
    image = np.asarray(image)
    cam = rig.cameras[c]
    allowed = (np.uint8,) if video else (np.uint8, np.uint16)
    if image.dtype not in allowed or image.ndim not in (2, 3) or (
            image.ndim == 3 and image.shape[2] != 3):
        kinds = "uint8" if video else "uint8 or uint16"
        raise DatasetError(f"{where}: camera {cam.name!r} image must be {kinds} (H, W) or "
                           f"(H, W, 3), got {image.dtype} {image.shape}")
    h, w = image.shape[:2]
    if (w, h) != (cam.width, cam.height):
        raise DatasetError(f"{where}: camera {cam.name!r} expects {cam.width}x{cam.height} "
                           f"images (rig), got {w}x{h}")
    return image


def _read_json(path: Path) -> dict:
    return read_json_object(path, DatasetError, "file")


def _atomic_save(path: Path, save: Callable[[Path], None]) -> None:
    """Let ``save`` write a temporary file beside ``path``, then rename it over ``path``."""
    tmp = path.with_name(f".{path.stem}.tmp{path.suffix}")
    try:
        save(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        raise DatasetError(f"{path}: cannot write ({exc.strerror or exc})") from None


def _same_rig(a: Rig, b: Rig) -> bool:
    """Whether two rigs have the same cameras (names, sizes, projection, calibration)."""
    if a.names != b.names:
        return False
    for ca, cb in zip(a.cameras, b.cameras, strict=True):
        if (ca.width, ca.height, ca.projection) != (cb.width, cb.height, cb.projection):
            return False
        for x, y in ((ca.K, cb.K), (ca.dist, cb.dist), (ca.T_cam_world, cb.T_cam_world),
                     (ca.depth_mm, cb.depth_mm)):
            if not np.allclose(x, y, rtol=1e-9, atol=1e-9):
                return False
    return True


# --------------------------------------------------------------------------- truth files
def _frame_numbers(cells: list[str]) -> list[int | None]:
    """The cells of a ``frame`` column as integers (None where a cell is not one)."""
    out: list[int | None] = []
    for cell in cells:
        try:
            out.append(int(cell))
        except ValueError:
            out.append(None)
    return out



def _write_truth(folder: Path, model: KinematicModel, truths: list[FrameTruth]) -> None:
    (folder / "truth").mkdir(exist_ok=True)
    states = np.array([t.state for t in truths])
    _atomic_save(folder / TRUTH_STATES, lambda tmp: write_states_csv(
        model, tmp, states, extra={"frame": range(len(truths))}))
    names = truths[0].keypoint_names
    arrays = {
        "names": np.array(names, dtype=str),
        "keypoints_3d": np.array([t.keypoints_3d for t in truths], dtype=float).reshape(
            len(truths), len(names), 3),
        "keypoints_2d": np.array([t.keypoints_2d for t in truths], dtype=float).reshape(
            len(truths), -1, len(names), 2),
        "visible": np.array([t.visible for t in truths], dtype=bool).reshape(
            len(truths), -1, len(names)),
    }
    _atomic_save(folder / TRUTH_KEYPOINTS, lambda tmp: np.savez_compressed(tmp, **arrays))


def read_ground_truth(folder: str | Path, spec: dict | None, model: KinematicModel,
                      n_cameras: int, n_frames: int, complete: bool = True
                      ) -> GroundTruth | None:
    """Read the ``truth`` entry of sequence.json (``spec``) for a folder.

    ``spec`` is ``{"states": "truth/states.csv" | null, "keypoints": "truth/keypoints.npz"
    | null}``. A complete sequence needs exactly ``n_frames`` truth rows; an incomplete one
    at least that many (extra rows from an interrupted checkpoint are dropped).
    """
    if spec is None:
        return None
    folder = Path(folder)
    if not isinstance(spec, dict) or not ({"states", "keypoints"} & set(spec)):
        raise DatasetError(f"{folder / SEQUENCE_FILE}: 'truth' must be null or an object with "
                           "'states' and/or 'keypoints' file names")

    def check_length(path: Path, length: int) -> None:
        if length < n_frames or (complete and length != n_frames):
            raise DatasetError(f"{path}: holds truth for {length} frames, expected {n_frames} "
                               f"(n_frames in {SEQUENCE_FILE})")

    states = None
    if spec.get("states"):
        path = inside(folder, spec["states"], "truth states file", str(folder / SEQUENCE_FILE))
        if not path.is_file():
            raise DatasetError(f"{path}: missing ground-truth states file")
        try:
            states, extra = read_states_csv(model, path)
        except StateError as exc:
            raise DatasetError(str(exc)) from None
        check_length(path, len(states))
        if "frame" in extra and _frame_numbers(extra["frame"]) != list(range(len(states))):
            raise DatasetError(f"{path}: column 'frame' must count 0, 1, 2, ...")
        states = states[:n_frames]
    names: tuple[str, ...] = ()
    kp3 = np.zeros((n_frames, 0, 3))
    kp2 = np.zeros((n_frames, n_cameras, 0, 2))
    vis = np.zeros((n_frames, n_cameras, 0), dtype=bool)
    if spec.get("keypoints"):
        path = inside(folder, spec["keypoints"], "truth keypoints file",
                      str(folder / SEQUENCE_FILE))
        try:
            with open(path, "rb") as handle, np.load(handle, allow_pickle=False) as data:
                arrays = {k: data[k] for k in ("names", "keypoints_3d", "keypoints_2d",
                                                "visible")}
        except FileNotFoundError:
            raise DatasetError(f"{path}: missing ground-truth keypoints file") from None
        except KeyError as exc:
            raise DatasetError(f"{path}: lacks array {exc.args[0]}") from None
        except (OSError, ValueError, EOFError, NotImplementedError, RuntimeError,
                zipfile.BadZipFile, zlib.error) as exc:
            raise DatasetError(f"{path}: not a readable .npz file ({exc})") from None
        names = tuple(str(n) for n in arrays["names"])
        k = len(names)
        t = len(arrays["keypoints_3d"])
        check_length(path, t)
        expected = {"keypoints_3d": (t, k, 3), "keypoints_2d": (t, n_cameras, k, 2),
                    "visible": (t, n_cameras, k)}
        for key, shape in expected.items():
            if arrays[key].shape != shape:
                raise DatasetError(f"{path}: {key} has shape {arrays[key].shape}, expected "
                                   f"{shape} (T frames, {n_cameras} cameras, {k} names)")
        kp3 = arrays["keypoints_3d"][:n_frames].astype(float)
        kp2 = arrays["keypoints_2d"][:n_frames].astype(float)
        vis = arrays["visible"][:n_frames].astype(bool)
    return GroundTruth(states, names, kp3, kp2, vis)


# --------------------------------------------------------------------------- writer
class SequenceWriter:
    """Write a sequence folder frame by frame (context manager).

    Parameters
    ----------
    folder : the sequence folder (created if needed).
    model : the kinematic model; its file text is copied to ``model.dh`` (pass
        ``model_text`` when the model was not read from a file).
    rig : the cameras; one image per camera and frame, sizes as in the rig.
    initial_state : (n_q,) state the trackers start from.
    fps : frames per second of the sequence.
    name : sequence name (default: the folder name). scenario : free JSON metadata.
    video : False for PNG frames; True or ``"ffv1"`` for one lossless FFV1 ``.mkv`` per
        camera; ``"h264"`` for one lossy H.264 ``.mp4`` per camera.
    crf : H.264 constant rate factor (:class:`~digiteyes.io.video.VideoWriter`).
    overwrite : replace an existing sequence in ``folder``.
    resume : continue an incomplete PNG sequence after its last complete frame; the next
        frame to write is ``writer.n_written``. Starts afresh if the folder holds none.
    checkpoint_every : rewrite truth and ``sequence.json`` every this many frames.

    Crash safety: every file is written to a temporary name and renamed into place;
    ``sequence.json`` is written at the start with ``"complete": false, "n_frames": 0`` and
    rewritten at every checkpoint and at :meth:`close` with the number of complete frames,
    after the truth files, so an interrupted render leaves a dataset that
    :func:`open_sequence` reads with exactly the frames it says. Video sequences count
    their frames only when the video files are finalised (at close, or when an exception
    leaves the ``with`` block); they cannot be resumed.
    """

    def __init__(self, folder: str | Path, model: KinematicModel, rig: Rig,
                 initial_state: np.ndarray, fps: float, *, name: str = "",
                 scenario: dict | None = None, video: bool | str = False,
                 crf: int = DEFAULT_H264_CRF, overwrite: bool = False, resume: bool = False,
                 checkpoint_every: int = CHECKPOINT_EVERY, model_text: str | None = None
                 ) -> None:
        self.folder = Path(folder)
        self.model = model
        self.rig = rig
        for cam in rig.cameras:
            check_name(cam.name, "camera name", str(self.folder))
        self.fps = float(fps)
        if not np.isfinite(self.fps) or self.fps <= 0:
            raise DatasetError(f"{self.folder}: fps must be positive, got {fps}")
        self.name = name or self.folder.name
        self.scenario = dict(scenario or {})
        try:
            json.dumps(self.scenario, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise DatasetError(f"{self.folder}: scenario must be plain JSON data ({exc})"
                               ) from None
        self.codec = None if not video else ("ffv1" if video is True else str(video))
        if self.codec is not None and self.codec not in VIDEO_CODECS:
            raise DatasetError(f"unknown video codec {video!r}; expected True, "
                               f"{', '.join(map(repr, VIDEO_CODECS))} or False")
        self.crf = checked_crf(crf)
        self.checkpoint_every = max(1, int(checkpoint_every))
        self.initial_state = State(model, np.asarray(initial_state, dtype=float))
        self.model_text = self._model_text(model_text)
        self.n_written = 0
        self._truths: list[FrameTruth] = []
        self._has_truth: bool | None = None
        self._color: str | None = None
        self._videos: list[VideoWriter] = []
        self._closed = False
        existing = self._existing(overwrite)
        if resume and existing is not None and not overwrite:
            self._resume(existing)
        else:
            self._start(existing, overwrite)

    # ------------------------------------------------------------- setup
    def _model_text(self, model_text: str | None) -> str:
        if model_text is not None:
            return model_text
        try:
            return Path(self.model.path).read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError, TypeError):
            raise DatasetError(f"model {self.model.name!r} was not read from a file "
                               f"({self.model.path}); pass model_text=") from None

    def _existing(self, overwrite: bool) -> dict | None:
        path = self.folder / SEQUENCE_FILE
        if not path.exists():
            return None
        try:
            return _read_json(path)
        except DatasetError:
            if overwrite:
                return {}
            raise

    def _start(self, existing: dict | None, overwrite: bool) -> None:
        folder = self.folder
        if existing is not None and not overwrite:
            if existing.get("complete"):
                raise DatasetError(f"{folder}: already holds a complete sequence; pass "
                                   "overwrite=True (--force) to replace it")
            raise DatasetError(
                f"{folder}: holds an incomplete sequence ({existing.get('n_frames', 0)} "
                "complete frames); pass resume=True (--resume) to continue after its last "
                "complete frame, or overwrite=True (--force) to start again")
        if existing is None and not overwrite and folder.is_dir() and any(folder.iterdir()):
            raise DatasetError(f"{folder}: folder is not empty and holds no sequence; choose "
                               "an empty folder or pass overwrite=True (--force)")
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise DatasetError(f"{folder}: cannot create folder ({exc.strerror or exc})"
                               ) from None
        if existing is not None:
            self._remove_old(existing)
        _atomic_write(folder / MODEL_FILE, self.model_text.encode("utf-8"))
        _atomic_save(folder / RIG_FILE, lambda tmp: save_rig(self.rig, tmp))
        _atomic_save(folder / INITIAL_STATE_FILE, self.initial_state.save_json)
        if self.codec is None:
            for cam in self.rig.cameras:
                try:
                    (folder / cam.name).mkdir(exist_ok=True)
                except OSError as exc:
                    raise DatasetError(f"{folder / cam.name}: cannot create folder "
                                       f"({exc.strerror or exc})") from None
        self._write_sequence_json(0, complete=False)

    def _remove_old(self, existing: dict) -> None:
        """Delete the frames and truth files of the sequence being overwritten: only
        plain names inside the folder (docs/safety.md); anything else is refused."""
        where = str(self.folder / SEQUENCE_FILE)
        frames = existing.get("frames")
        frames = frames if isinstance(frames, dict) else {}
        files = frames.get("files") if isinstance(frames, dict) else None
        cameras = existing.get("cameras") or []
        if not isinstance(files or {}, dict) or not isinstance(cameras, list):
            raise DatasetError(f"{where}: 'frames.files' and 'cameras' are malformed; remove "
                               "the old sequence yourself")
        old = [self.folder / TRUTH_STATES, self.folder / TRUTH_KEYPOINTS]
        old += [self.folder / check_name(f, "video file", where)
                for f in (files or {}).values()]
        for cam in cameras:
            cam_dir = self.folder / check_name(cam, "camera", where)
            if frames.get("kind") == "png" and cam_dir.is_dir() and not cam_dir.is_symlink():
                old += [*cam_dir.glob("[0-9]*.png"), *cam_dir.glob(".*.tmp")]
        for path in old:
            if path.is_symlink() or path.is_dir():
                continue
            try:
                path.unlink(missing_ok=True)
            except OSError as exc:
                raise DatasetError(f"{path}: cannot remove the old frame ({exc.strerror or exc})"
                                   ) from None

    def _resume(self, existing: dict) -> None:
        folder = self.folder
        where = folder / SEQUENCE_FILE
        if existing.get("complete"):
            raise DatasetError(f"{folder}: the sequence is already complete; nothing to resume "
                               "(pass overwrite=True (--force) to write it again)")
        frames = existing.get("frames")
        if self.codec is not None or not isinstance(frames, dict) or frames.get("kind") != "png":
            raise DatasetError(f"{folder}: only PNG sequences can be resumed; pass "
                               "overwrite=True (--force) to start again")
        old_text = (folder / MODEL_FILE).read_text(encoding="utf-8") \
            if (folder / MODEL_FILE).is_file() else None
        if old_text != self.model_text:
            raise DatasetError(f"{folder / MODEL_FILE}: differs from the model being written; "
                               "cannot resume")
        if not _same_rig(load_rig(folder / RIG_FILE), self.rig):
            raise DatasetError(f"{folder / RIG_FILE}: differs from the rig being written; "
                               "cannot resume")
        if existing.get("fps") != self.fps:
            raise DatasetError(f"{where}: fps {existing.get('fps')} differs from {self.fps}; "
                               "cannot resume")
        n = existing.get("n_frames", 0)
        if not isinstance(n, int) or n < 0:
            raise DatasetError(f"{where}: n_frames must be an integer >= 0, got {n!r}")
        truth = read_ground_truth(folder, existing.get("truth"), self.model, len(self.rig),
                                  n, complete=False)
        if truth is not None and n > 0:
            if truth.states is None:
                raise DatasetError(f"{where}: truth without states cannot be resumed")
            self._has_truth = True
            self._truths = [
                FrameTruth(truth.states[i], truth.keypoint_names, truth.keypoints_3d[i],
                           truth.keypoints_2d[i], truth.visible[i]) for i in range(n)]
        elif n > 0:
            self._has_truth = False
        self.n_written = n

    # ------------------------------------------------------------- writing
    def _sequence_payload(self, n_frames: int, complete: bool) -> dict:
        if self.codec is None:
            frames: dict = {"kind": "png", "pattern": PNG_PATTERN}
        else:
            suffix = VIDEO_CODECS[self.codec][0]
            frames = {"kind": "video", "codec": self.codec,
                      "lossless": VIDEO_CODECS[self.codec][2],
                      "color": self._color or "rgb",
                      "files": {c.name: f"{c.name}{suffix}" for c in self.rig.cameras}}
        truth = None
        if self._has_truth:
            truth = {"states": TRUTH_STATES, "keypoints": TRUTH_KEYPOINTS}
        return {
            "format": FORMAT, "version": VERSION, "name": self.name,
            "model": MODEL_FILE, "rig": RIG_FILE, "initial_state": INITIAL_STATE_FILE,
            "fps": self.fps, "n_frames": n_frames, "complete": complete,
            "cameras": self.rig.names, "frames": frames, "truth": truth,
            "scenario": self.scenario, "written_by": f"digiteyes {__version__}",
        }

    def _write_sequence_json(self, n_frames: int, complete: bool) -> None:
        text = json.dumps(self._sequence_payload(n_frames, complete), indent=2) + "\n"
        _atomic_write(self.folder / SEQUENCE_FILE, text.encode("utf-8"))

    def _check_truth(self, truth: FrameTruth | None) -> None:
        where = f"{self.folder}: frame {self.n_written}"
        if self._has_truth is not None and self._has_truth != (truth is not None):
            raise DatasetError(f"{where}: give ground truth for every frame or for none")
        if truth is None:
            return
        if np.shape(truth.state) != (self.model.n_q,):
            raise DatasetError(f"{where}: truth state must have {self.model.n_q} numbers, "
                               f"got shape {np.shape(truth.state)}")
        k, c = len(truth.keypoint_names), len(self.rig)
        shapes = {"keypoints_3d": (k, 3), "keypoints_2d": (c, k, 2), "visible": (c, k)}
        for key, shape in shapes.items():
            if np.shape(getattr(truth, key)) != shape:
                raise DatasetError(f"{where}: truth {key} must have shape {shape}, got "
                                   f"{np.shape(getattr(truth, key))}")
        if self._truths and tuple(truth.keypoint_names) != self._truths[0].keypoint_names:
            raise DatasetError(f"{where}: keypoint names differ from the first frame's")

    def write_frame(self, images: SequenceABC[np.ndarray],
                    truth: FrameTruth | None = None) -> None:
        """Write the images of the next frame (one per camera) and its ground truth."""
        if self._closed:
            raise DatasetError(f"{self.folder}: writer is closed")
        where = f"{self.folder}: frame {self.n_written}"
        if len(images) != len(self.rig):
            raise DatasetError(f"{where}: the rig has {len(self.rig)} camera(s) "
                               f"({', '.join(self.rig.names)}), got {len(images)} image(s)")
        checked = [_check_image(im, self.rig, c, where, self.codec is not None)
                   for c, im in enumerate(images)]
        self._check_truth(truth)
        if self.codec is None:
            for cam, image in zip(self.rig.cameras, checked, strict=True):
                path = self.folder / PNG_PATTERN.format(camera=cam.name, index=self.n_written)
                _atomic_write(path, _encode_png(image, str(path)))
        else:
            self._write_video(checked)
        if truth is not None:
            self._truths.append(FrameTruth(
                np.array(truth.state, dtype=float), tuple(truth.keypoint_names),
                np.array(truth.keypoints_3d, dtype=float),
                np.array(truth.keypoints_2d, dtype=float), np.array(truth.visible, dtype=bool)))
        self._has_truth = truth is not None
        self.n_written += 1
        if self.n_written % self.checkpoint_every == 0:
            self.checkpoint()

    def _write_video(self, images: list[np.ndarray]) -> None:
        colors = {"gray" if im.ndim == 2 else "rgb" for im in images}
        if len(colors) > 1 or (self._color is not None and colors != {self._color}):
            raise DatasetError(f"{self.folder}: frame {self.n_written}: video sequences need "
                               "all cameras and frames grey or all RGB")
        if not self._videos:
            self._color = colors.pop()
            suffix = VIDEO_CODECS[self.codec][0]
            self._videos = [VideoWriter(self.folder / f"{c.name}{suffix}", self.fps, self.codec,
                                        self.crf)
                            for c in self.rig.cameras]
        for writer, image in zip(self._videos, images, strict=True):
            writer.write(image)

    def checkpoint(self) -> None:
        """Flush truth files, then ``sequence.json`` with the complete frame count."""
        if self._has_truth and self._truths:
            _write_truth(self.folder, self.model, self._truths)
        self._write_sequence_json(self.n_written if self.codec is None else 0, complete=False)

    def _finish(self, complete: bool) -> None:
        if self._closed:
            return
        self._closed = True
        for writer in self._videos:
            writer.close()
        if self._has_truth and self._truths:
            _write_truth(self.folder, self.model, self._truths)
        self._write_sequence_json(self.n_written, complete=complete)

    def close(self) -> None:
        """Finish: write truth files and the final ``sequence.json`` (``complete: true``)."""
        self._finish(complete=True)

    def abort(self) -> None:
        """Stop without marking the sequence complete (what an exception in ``with`` does)."""
        self._finish(complete=False)

    def __enter__(self) -> SequenceWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


# --------------------------------------------------------------------------- reader
class Sequence:
    """A sequence folder opened for reading (see :func:`open_sequence`).

    Attributes: ``folder``, ``name``, ``model`` (KinematicModel from ``model.dh``), ``rig``,
    ``initial_state`` ((n_q,) array), ``fps``, ``n_frames`` (complete frames),
    ``complete`` (False after an interrupted write), ``camera_names``, ``truth``
    (:class:`GroundTruth` or None), ``scenario`` (dict), ``frames_spec``.
    ``frame(i)`` returns one image per camera; iterating yields every frame in order.
    """

    def __init__(self, folder: Path, payload: dict) -> None:
        self.folder = folder
        where = folder / SEQUENCE_FILE
        self._where = where
        if payload.get("format") != FORMAT:
            raise DatasetError(f"{where}: 'format' must be {FORMAT!r}, got "
                               f"{payload.get('format')!r}")
        if payload.get("version") != VERSION:
            raise DatasetError(f"{where}: unsupported version {payload.get('version')!r}; this "
                               f"digiteyes reads version {VERSION}")
        for key in ("model", "rig", "initial_state", "fps", "n_frames", "cameras", "frames"):
            if key not in payload:
                raise DatasetError(f"{where}: missing key {key!r}")
        self.name = str(payload.get("name") or folder.name)
        fps, n_frames = payload["fps"], payload["n_frames"]
        if isinstance(fps, bool) or not isinstance(fps, (int, float)) \
                or isinstance(n_frames, bool) or not isinstance(n_frames, int) \
                or n_frames < 0 or not np.isfinite(fps) or fps <= 0:
            raise DatasetError(f"{where}: n_frames must be an integer >= 0 and fps a number "
                               f"> 0, got {n_frames!r} and {fps!r}")
        self.fps = float(fps)
        self.n_frames = n_frames
        self.complete = bool(payload.get("complete", True))
        self.scenario = payload.get("scenario") or {}
        self.model = load_model(inside(folder, payload["model"], "model", str(where)))
        self.rig = load_rig(inside(folder, payload["rig"], "rig", str(where)))
        if not isinstance(payload["cameras"], list):
            raise DatasetError(f"{where}: 'cameras' must be a list of names")
        self.camera_names = [check_name(c, "camera", str(where)) for c in payload["cameras"]]
        if self.camera_names != self.rig.names:
            raise DatasetError(f"{where}: cameras {self.camera_names} do not match the rig "
                               f"file's cameras {self.rig.names}")
        self.initial_state = State.load_json(
            self.model, inside(folder, payload["initial_state"], "initial state", str(where))).q
        self.frames_spec = payload["frames"]
        self._readers: list[VideoReader] | None = None
        self._check_frames()
        self.truth = read_ground_truth(folder, payload.get("truth"), self.model, len(self.rig),
                                       self.n_frames, complete=self.complete)

    # ------------------------------------------------------------- frames
    def _check_frames(self) -> None:
        spec, where = self.frames_spec, self._where
        kind = spec.get("kind") if isinstance(spec, dict) else None
        if kind == "png":
            self._pattern = str(spec.get("pattern", PNG_PATTERN))
            self._first = spec.get("first_index", 0)
            if isinstance(self._first, bool) or not isinstance(self._first, int) \
                    or not 0 <= self._first < 10**12:
                raise DatasetError(f"{where}: frames.first_index must be an integer >= 0")
            for cam in self.camera_names:
                try:
                    relative = self._pattern.format(camera=cam, index=self._first)
                except (KeyError, IndexError, ValueError, AttributeError, TypeError):
                    raise DatasetError(f"{where}: frames.pattern {self._pattern[:60]!r} must "
                                       "use only {camera} and {index}") from None
                inside(self.folder, relative, "frames.pattern", str(where))
                if "{index" not in self._pattern or ".." in self._pattern:
                    raise DatasetError(f"{where}: frames.pattern must hold {{index}} and "
                                       "no '..'")
            for i in range(self.n_frames):
                for cam in self.camera_names:
                    path = self.image_path(cam, i)
                    if not path.is_file():
                        raise DatasetError(f"{path}: missing frame {i} of camera {cam!r} "
                                           f"({where} says n_frames={self.n_frames})")
            if self.n_frames:
                self.frame(0)
        elif kind == "video":
            files = spec.get("files")
            if not isinstance(files, dict) or set(files) != set(self.camera_names):
                raise DatasetError(f"{where}: frames.files must map every camera "
                                   f"({', '.join(self.camera_names)}) to a video file")
            self._videos = [self.folder / check_name(files[c], "video file", str(where))
                            for c in self.camera_names]
            for path in self._videos:
                if not path.is_file():
                    raise DatasetError(f"{path}: missing video file")
            self._gray = spec.get("color", "rgb") == "gray"
            if self.n_frames:
                self.frame(0)
        else:
            raise DatasetError(f"{where}: frames.kind must be 'png' or 'video', got {kind!r}")

    def image_path(self, camera: str, index: int) -> Path:
        """Path of the PNG of frame ``index`` (0-based) of ``camera`` (PNG sequences)."""
        return self.folder / self._pattern.format(camera=camera, index=index + self._first)

    def _check_sizes(self, images: list[np.ndarray], i: int, sources: list[Path]) -> None:
        for cam, image, source in zip(self.rig.cameras, images, sources, strict=True):
            h, w = image.shape[:2]
            if (w, h) != (cam.width, cam.height):
                raise DatasetError(f"{source}: frame {i} is {w}x{h}, but camera {cam.name!r} "
                                   f"in the rig expects {cam.width}x{cam.height}")

    def frame(self, i: int) -> list[np.ndarray]:
        """Images of frame ``i``, one per camera in rig order."""
        if not 0 <= i < self.n_frames:
            raise IndexError(f"frame {i} out of range 0..{self.n_frames - 1}")
        if self.frames_spec["kind"] == "png":
            paths = [self.image_path(cam, i) for cam in self.camera_names]
            images = [read_png(p) for p in paths]
            self._check_sizes(images, i, paths)
            return images
        if self._readers is None or self._readers[0].n_read > i:
            self.close()
            self._readers = [VideoReader(p, gray=self._gray) for p in self._videos]
        images: list[np.ndarray] = []
        for reader in self._readers:
            image = None
            while reader.n_read <= i:
                image = reader.read()
                if image is None:
                    raise DatasetError(f"{reader.path}: ends after {reader.n_read} frames, but "
                                       f"{self._where} says n_frames={self.n_frames}")
            images.append(image)
        self._check_sizes(images, i, self._videos)
        return images

    def __len__(self) -> int:
        return self.n_frames

    def __iter__(self) -> Iterator[list[np.ndarray]]:
        for i in range(self.n_frames):
            yield self.frame(i)

    def close(self) -> None:
        """Release open video files (PNG sequences hold none)."""
        for reader in self._readers or []:
            reader.close()
        self._readers = None

    def __enter__(self) -> Sequence:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return (f"Sequence({str(self.folder)!r}, model={self.model.name!r}, "
                f"cameras={self.camera_names}, n_frames={self.n_frames}, "
                f"truth={self.truth is not None})")


def open_sequence(folder: str | Path) -> Sequence:
    """Open a sequence folder and check that its parts agree.

    Raises :class:`DatasetError` naming the file and what was expected when a part is
    missing or disagrees (missing frames, image sizes other than the rig's, truth of
    another length than ``n_frames``); errors in the model, rig and state files pass through
    as :class:`~digiteyes.errors.ModelFileError`, ``CameraError`` and ``StateError``, which
    name their file.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise DatasetError(f"{folder}: no such sequence folder")
    return Sequence(folder, _read_json(folder / SEQUENCE_FILE))
