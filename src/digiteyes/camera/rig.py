"""Camera rigs: any number of calibrated cameras in one world frame (thesis Sec. 2.5.5).

A rig file is JSON (documented in docs/cameras.md)::

    {"cameras": [
      {"name": "left", "width": 640, "height": 480,
       "K": [[822.8, 0, 318.5], [0, 822.8, 250.3], [0, 0, 1]],
       "dist": [0, 0, 0, 0, 0],
       "projection": "perspective",
       "T_cam_world": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}
    ]}

Instead of ``T_cam_world`` a camera may give OpenCV's ``rvec`` + ``tvec`` (world to
camera), and instead of ``K``/``dist``/size an ``opencv`` entry naming an OpenCV
calibration file (YAML or XML from ``cv::FileStorage``, keys ``camera_matrix``,
``distortion_coefficients``, ``image_width``, ``image_height``; optional ``rvec``/``tvec``
or ``R``/``T``) relative to the rig file. A bare OpenCV calibration file also loads as a
one-camera rig.
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from digiteyes.camera.camera import Camera
from digiteyes.camera.reflection import unmirror_pixels
from digiteyes.errors import CameraError
from digiteyes.jsonfile import read_json_object


@dataclass(frozen=True)
class Rig:
    """An ordered set of cameras sharing one world frame.

    ``mirrored``: the cameras see the mirror image of the real scene, through images
    flipped left to right (a left hand tracked by a right-hand model,
    :mod:`digiteyes.camera.mirror`); outputs in image and camera coordinates are turned
    back to the real images.

    ``real_sizes``: ``(width, height)`` per camera of the real images when the cameras see
    them resized to a working size (:mod:`digiteyes.camera.working_size`); None when they
    see the real images. :meth:`real_pixels` maps pixels back in both cases.
    """

    cameras: tuple[Camera, ...]
    mirrored: bool = False
    real_sizes: tuple[tuple[int, int], ...] | None = None

    def __post_init__(self) -> None:
        if not self.cameras:
            raise CameraError("a rig needs at least one camera")
        names = [c.name for c in self.cameras]
        if len(set(names)) != len(names):
            raise CameraError(f"camera names in a rig must be unique, got {names}")

    def __len__(self) -> int:
        return len(self.cameras)

    def __iter__(self) -> Iterator[Camera]:
        return iter(self.cameras)

    def __getitem__(self, index: int) -> Camera:
        return self.cameras[index]

    def real_pixels(self, uv: np.ndarray, index: int) -> np.ndarray:
        """Pixels (..., 2) of camera ``index``'s images, in the real images: unflipped for
        a mirrored rig, then scaled back from the working size (pixel centres at
        integers, so ``u_real = (u + 1/2) W_real / W - 1/2``)."""
        camera = self.cameras[index]
        out = np.array(uv, dtype=float)
        if self.mirrored:
            out = unmirror_pixels(out, camera.width)
        if self.real_sizes is not None:
            width, height = self.real_sizes[index]
            out[..., 0] = (out[..., 0] + 0.5) * (width / camera.width) - 0.5
            out[..., 1] = (out[..., 1] + 0.5) * (height / camera.height) - 0.5
        return out

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.cameras]

    def check_images(self, images: Sequence[np.ndarray]) -> None:
        """Raise :class:`CameraError` unless there is one image of the right size per camera."""
        if len(images) != len(self.cameras):
            raise CameraError(
                f"the rig has {len(self.cameras)} camera(s) ({', '.join(self.names)}) but "
                f"{len(images)} image(s) were given"
            )
        for cam, image in zip(self.cameras, images, strict=True):
            h, w = np.asarray(image).shape[:2]
            if (w, h) != (cam.width, cam.height):
                raise CameraError(
                    f"camera {cam.name!r} expects {cam.width}x{cam.height} images, got {w}x{h}"
                )


def _camera_to_json(cam: Camera) -> dict:
    return {
        "name": cam.name,
        "width": cam.width,
        "height": cam.height,
        "K": cam.K.tolist(),
        "dist": cam.dist.tolist(),
        "projection": cam.projection,
        "depth_mm": cam.depth_mm,
        "T_cam_world": cam.T_cam_world.tolist(),
    }


def save_rig(rig: Rig, path: str | Path) -> None:
    """Write a rig file (JSON)."""
    payload = {"cameras": [_camera_to_json(c) for c in rig.cameras]}
    Path(path).write_text(json.dumps(payload, indent=2) + "\n", encoding="utf-8")


def _read_opencv(path: Path) -> dict:
    """Read an OpenCV FileStorage calibration (YAML/XML) into plain arrays."""
    if not path.exists():
        raise CameraError(f"{path}: no such OpenCV calibration file")
    try:
        storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except (cv2.error, SystemError) as exc:
        # OpenCV 5 wraps parse errors of FileStorage in SystemError.
        cause = exc if isinstance(exc, cv2.error) else exc.__cause__
        detail = getattr(cause, "err", None) or str(exc)
        raise CameraError(f"{path}: not an OpenCV calibration file ({detail})") from None
    try:
        if not storage.isOpened() or not storage.root().isMap():
            raise CameraError(f"{path}: not an OpenCV calibration file (expected a map of "
                              "camera_matrix, image_width, ...)")
        out: dict = {}
        for key in ("camera_matrix", "distortion_coefficients", "rvec", "tvec", "R", "T"):
            node = storage.getNode(key)
            if not node.empty():
                out[key] = _opencv_matrix(node, key, path)
        for key in ("image_width", "image_height"):
            node = storage.getNode(key)
            if not node.empty():
                out[key] = _opencv_size(node, key, path)
    except (cv2.error, SystemError) as exc:
        raise CameraError(f"{path}: not an OpenCV calibration file ({exc})") from None
    finally:
        storage.release()
    for key in ("camera_matrix", "image_width", "image_height"):
        if key not in out:
            raise CameraError(f"{path}: OpenCV calibration lacks '{key}'")
    return out


MAX_OPENCV_ELEMENTS = 64
"""Most numbers an OpenCV calibration matrix may hold (a 3x3 K has 9)."""
MAX_IMAGE_SIDE = 65_536
"""Largest image width or height accepted (pixels)."""


def _opencv_number(node: cv2.FileNode, what: str, path: Path) -> float:
    if not (node.isInt() or node.isReal()):
        raise CameraError(f"{path}: {what} must be a number")
    value = node.real()
    if not np.isfinite(value) or abs(value) >= 1e300:
        raise CameraError(f"{path}: {what} must be a finite number")
    return value


def _opencv_matrix(node: cv2.FileNode, key: str, path: Path) -> np.ndarray:
    """A ``!!opencv-matrix`` node read element by element, its ``rows``, ``cols``, ``dt``
    and ``data`` checked first (``FileNode.mat()`` trusts them and can corrupt memory)."""
    if not node.isMap():
        raise CameraError(f"{path}: '{key}' must be an opencv-matrix with rows, cols, dt "
                          "and data")
    parts = {name: node.getNode(name) for name in ("rows", "cols", "dt", "data")}
    missing = [name for name, part in parts.items() if part.empty()]
    if missing:
        raise CameraError(f"{path}: '{key}' lacks {', '.join(missing)}")
    if not parts["dt"].isString():
        raise CameraError(f"{path}: '{key}': dt must be a type letter such as d")
    shape = []
    for name in ("rows", "cols"):
        value = _opencv_number(parts[name], f"'{key}' {name}", path)
        if not parts[name].isInt() or not 1 <= value <= MAX_OPENCV_ELEMENTS:
            raise CameraError(f"{path}: '{key}' {name} must be an integer from 1 to "
                              f"{MAX_OPENCV_ELEMENTS}")
        shape.append(int(value))
    data = parts["data"]
    count = shape[0] * shape[1]
    if not data.isSeq() or data.size() != count:
        raise CameraError(f"{path}: '{key}' data must list rows x cols = {count} numbers")
    values = [_opencv_number(data.at(i), f"'{key}' data", path) for i in range(count)]
    return np.array(values, dtype=float).reshape(shape)


def _opencv_size(node: cv2.FileNode, key: str, path: Path) -> int:
    value = _opencv_number(node, f"'{key}'", path)
    if not float(value).is_integer() or not 1 <= value <= MAX_IMAGE_SIDE:
        raise CameraError(f"{path}: '{key}' must be an integer from 1 to {MAX_IMAGE_SIDE}")
    return int(value)


def _extrinsics(entry: dict, where: str) -> np.ndarray:
    if "T_cam_world" in entry:
        return np.asarray(entry["T_cam_world"], dtype=float)
    T = np.eye(4)
    if "rvec" in entry or "tvec" in entry:
        try:
            rvec = np.asarray(entry["rvec"], dtype=float).reshape(3)
            tvec = np.asarray(entry["tvec"], dtype=float).reshape(3)
        except (KeyError, ValueError):
            raise CameraError(f"{where}: rvec and tvec must both be 3-vectors") from None
        T[:3, :3] = cv2.Rodrigues(rvec)[0]
        T[:3, 3] = tvec
    elif "R" in entry and "T" in entry:
        T[:3, :3] = np.asarray(entry["R"], dtype=float).reshape(3, 3)
        T[:3, 3] = np.asarray(entry["T"], dtype=float).reshape(3)
    return T


def _camera_from_entry(entry: dict, base: Path, index: int, where: str) -> Camera:
    if not isinstance(entry, dict):
        raise CameraError(f"{where}: camera {index} must be an object")
    name = str(entry.get("name", f"cam{index}"))
    values = dict(entry)
    if "opencv" in entry:
        try:
            calib = _read_opencv(base / str(entry["opencv"]))
        except CameraError as exc:
            raise CameraError(f"{where}: camera {name!r}: {exc}") from None
        values.setdefault("K", calib["camera_matrix"])
        values.setdefault("dist", calib.get("distortion_coefficients"))
        values.setdefault("width", calib["image_width"])
        values.setdefault("height", calib["image_height"])
        for key in ("rvec", "tvec", "R", "T"):
            if key in calib and not {"T_cam_world", "rvec", "tvec", "R", "T"} & set(entry):
                values[key] = calib[key]
    for key in ("K", "width", "height"):
        if key not in values:
            raise CameraError(f"{where}: camera {name!r} lacks '{key}'")
    try:
        return Camera.create(
            name,
            np.asarray(values["K"], dtype=float),
            values["width"],
            values["height"],
            _extrinsics(values, where),
            None if values.get("dist") is None else np.asarray(values["dist"], dtype=float),
            values.get("projection", "perspective"),
            float(values.get("depth_mm", 1000.0)),
        )
    except CameraError as exc:
        raise CameraError(f"{where}: {exc}") from None
    except (TypeError, ValueError) as exc:
        raise CameraError(f"{where}: camera {name!r}: {exc}") from None


def load_rig(path: str | Path) -> Rig:
    """Load a rig from a JSON rig file or a single OpenCV calibration file (YAML/XML)."""
    path = Path(path)
    if path.suffix.lower() in (".yml", ".yaml", ".xml"):
        return Rig((_camera_from_entry({"name": path.stem, "opencv": path.name}, path.parent,
                                       0, str(path)),))
    expected = "a rig: an object with a 'cameras' list"
    payload = read_json_object(path, CameraError, "rig file", expected)
    if not isinstance(payload.get("cameras"), list):
        raise CameraError(f"{path}: expected {expected}")
    cams = tuple(_camera_from_entry(e, path.parent, i, str(path))
                 for i, e in enumerate(payload["cameras"]))
    try:
        return Rig(cams)
    except CameraError as exc:
        raise CameraError(f"{path}: {exc}") from None
