"""Video files through PyAV: one file per camera, decoded to numpy images.

Images are ``uint8`` arrays, ``(H, W)`` grayscale or ``(H, W, 3)`` RGB (red first).
Two codecs are offered for writing (docs/dataset.md explains the choice):

* ``"ffv1"`` (default): FFV1 in Matroska (``.mkv``), lossless, grey (``gray``) or colour
  (``bgr0``) pixels stored exactly, so ground truth and images stay consistent to the bit;
* ``"h264"``: libx264 in MP4 (``.mp4``, ``yuv420p``), lossy (chroma subsampled; constant
  rate factor 12 unless told, near lossless) but small and playable everywhere; needs even
  image sizes. At CRF 12 the sensor noise of a rendered frame is kept, which costs some
  80 KB per 640 x 480 frame; x264's own default, CRF 23, gives about 2 KB, the order of
  a phone recording (docs/benchmarks.md, section (b)).
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from fractions import Fraction
from pathlib import Path

import av
import cv2
import numpy as np

from digiteyes.errors import DatasetError

DEFAULT_FPS = 10.0
"""Frame rate assumed for frames whose source declares none (a video without a rate, a
state log without a summary), frames/s."""
DEFAULT_CAMERA_FPS = 30.0
"""Frame rate assumed for a live camera that reports none, frames/s."""
DEFAULT_H264_CRF = 12
"""H.264 constant rate factor of :class:`VideoWriter` (0 lossless .. 51 worst)."""
H264_PRESETS = ("ultrafast", "superfast", "veryfast", "faster", "fast", "medium", "slow",
                "slower", "veryslow")
"""x264's speed presets, fastest first (slower ones compress better at the same CRF)."""

#: codec name -> (file suffix, PyAV encoder, whether decoding returns the exact pixels)
VIDEO_CODECS: dict[str, tuple[str, str, bool]] = {
    "ffv1": (".mkv", "ffv1", True),
    "h264": (".mp4", "libx264", False),
}


def _container_format(path: Path) -> str | None:
    """FFmpeg muxer for a file name (the temporary name hides nothing: same suffix)."""
    return {".mp4": "mp4", ".mkv": "matroska", ".avi": "avi", ".mov": "mov"}.get(
        path.suffix.lower())


def _rate(fps: float) -> Fraction:
    """Frame rate as a fraction (29.97 -> 30000/1001)."""
    if not np.isfinite(fps) or fps <= 0:
        raise DatasetError(f"fps must be a positive number, got {fps}")
    return Fraction(fps).limit_denominator(1001)


def checked_crf(crf: int) -> int:
    """``crf`` as an int if it is a valid H.264 constant rate factor (0 to 51), else
    :class:`DatasetError`."""
    if isinstance(crf, bool) or not isinstance(crf, int | np.integer) or not 0 <= crf <= 51:
        raise DatasetError(f"H.264 crf must be an integer from 0 to 51, got {crf!r}")
    return int(crf)


class VideoWriter:
    """Encode images of one camera into a video file (context manager).

    Parameters
    ----------
    path : output file; its suffix should be that of the codec (``.mkv`` / ``.mp4``).
    fps : frames per second.
    codec : ``"ffv1"`` (lossless) or ``"h264"`` (lossy), see the module docstring.
    crf : H.264 constant rate factor, 0 (lossless) to 51 (worst); ignored for FFV1.
    preset : x264 speed preset (:data:`H264_PRESETS`); ignored for FFV1.

    The first image fixes the size and the colour (grey ``(H, W)`` or RGB ``(H, W, 3)``);
    later images must match. OSError (disk full, unwritable folder) becomes
    :class:`DatasetError` naming the file.
    """

    def __init__(self, path: str | Path, fps: float, codec: str = "ffv1",
                 crf: int = DEFAULT_H264_CRF, preset: str = "medium") -> None:
        if codec not in VIDEO_CODECS:
            raise DatasetError(f"unknown video codec {codec!r}; expected one of "
                               f"{', '.join(VIDEO_CODECS)}")
        if preset not in H264_PRESETS:
            raise DatasetError(f"unknown x264 preset {preset!r}; expected one of "
                               f"{', '.join(H264_PRESETS)}")
        self.crf = checked_crf(crf)
        self.preset = preset
        self.path = Path(path)
        self.codec = codec
        self.rate = _rate(fps)
        self.n_written = 0
        self._shape: tuple[int, ...] | None = None
        self._stream = None
        # Written under a temporary name, renamed on close: the final name never holds a
        # video without its index (unplayable), whatever stops the process.
        self._tmp = self.path.with_name(f".{self.path.stem}.part{self.path.suffix}")
        try:
            self._container = av.open(str(self._tmp), "w", format=_container_format(self.path))
        except (OSError, av.FFmpegError) as exc:
            raise DatasetError(f"{self.path}: cannot create video file ({exc})") from None

    def _open_stream(self, image: np.ndarray) -> None:
        h, w = image.shape[:2]
        encoder = VIDEO_CODECS[self.codec][1]
        if encoder == "libx264" and (h % 2 or w % 2):
            raise DatasetError(
                f"{self.path}: h264 needs even image sizes, got {w}x{h}; use the ffv1 codec"
            )
        stream = self._container.add_stream(encoder, rate=self.rate)
        stream.width, stream.height = w, h
        if encoder == "ffv1":
            stream.pix_fmt = "gray" if image.ndim == 2 else "bgr0"
        else:
            stream.pix_fmt = "yuv420p"
            stream.options = {"crf": str(self.crf), "preset": self.preset}
        self._stream = stream
        self._shape = image.shape

    def write(self, image: np.ndarray) -> None:
        """Encode one ``uint8`` image, grey ``(H, W)`` or RGB ``(H, W, 3)``."""
        image = np.ascontiguousarray(image)
        if image.dtype != np.uint8 or image.ndim not in (2, 3) or (
                image.ndim == 3 and image.shape[2] != 3):
            raise DatasetError(f"{self.path}: video frames must be uint8 (H, W) or (H, W, 3), "
                               f"got {image.dtype} {image.shape}")
        if self._stream is None:
            self._open_stream(image)
        elif image.shape != self._shape:
            raise DatasetError(f"{self.path}: frame {self.n_written} has shape {image.shape}, "
                               f"earlier frames {self._shape}")
        frame = av.VideoFrame.from_ndarray(image, format="gray" if image.ndim == 2 else "rgb24")
        try:
            for packet in self._stream.encode(frame):
                self._container.mux(packet)
        except (OSError, av.FFmpegError) as exc:
            raise DatasetError(f"{self.path}: cannot write video frame ({exc})") from None
        self.n_written += 1

    def close(self) -> None:
        """Flush the encoder and finalise the file (idempotent)."""
        if self._container is None:
            return
        container, self._container = self._container, None
        try:
            try:
                if self._stream is not None:
                    for packet in self._stream.encode():
                        container.mux(packet)
            finally:
                container.close()
            os.replace(self._tmp, self.path)
        except (OSError, av.FFmpegError) as exc:
            self._tmp.unlink(missing_ok=True)
            raise DatasetError(f"{self.path}: cannot finalise video file ({exc})") from None

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


#: pixel formats whose first plane is the luma (Y) channel at full image size
_LUMA_FIRST = frozenset({"yuv420p", "yuv422p", "yuv444p", "yuvj420p", "yuvj422p", "yuvj444p",
                         "nv12", "nv21"})
#: limited-range luma (16..235, ITU-R BT.601/709) to full-range grey (0..255)
_LIMITED_TO_FULL = np.clip(np.round((np.arange(256) - 16) * (255 / 219)), 0, 255
                           ).astype(np.uint8)


def _upright(image: np.ndarray, frame: av.VideoFrame) -> np.ndarray:
    """``image`` turned the way the container says it is shown: a phone records a portrait
    video as landscape frames plus a display rotation (multiples of 90 deg), which players
    and OpenCV apply and FFmpeg's decoder does not."""
    quarter_turns = round(frame.rotation / 90.0) % 4
    if not quarter_turns:
        return image
    return np.ascontiguousarray(np.rot90(image, quarter_turns))


def _gray_image(frame: av.VideoFrame) -> np.ndarray:
    """A decoded frame as a full-range grey ``uint8`` (H, W) image.

    Grey frames are copied as they are. For YUV frames the luma plane is read directly
    and, if it is limited range, stretched to 0..255 by a table: the same grey values
    as FFmpeg's own conversion, at a fraction of its cost (about 1.5 ms per
    640x480 frame saved). Other formats go through FFmpeg's conversion.
    """
    name = frame.format.name
    if name not in _LUMA_FIRST:
        return frame.to_ndarray(format="gray")
    plane = frame.planes[0]
    luma = np.frombuffer(plane, np.uint8).reshape(plane.height, plane.line_size)
    luma = luma[:, :plane.width]
    if name.startswith("yuvj") or frame.color_range == 2:  # 2: AVCOL_RANGE_JPEG (full)
        return luma.copy()
    return cv2.LUT(luma, _LIMITED_TO_FULL)


class VideoReader:
    """Decode one video file frame by frame (opened at once, so errors come early).

    ``read()`` returns the next image, ``uint8`` (H, W) if ``gray`` else (H, W, 3) RGB, or
    None at the end; ``n_read`` counts the frames returned so far. Iterating yields the
    remaining frames. Raises :class:`DatasetError` naming the file if it is missing, has no
    video stream or cannot be decoded.
    """

    def __init__(self, path: str | Path, *, gray: bool = False) -> None:
        self.path = Path(path)
        self.gray = gray
        self.n_read = 0
        try:
            self._container = av.open(str(self.path))
        except (OSError, av.FFmpegError) as exc:
            raise DatasetError(f"{self.path}: cannot open video ({exc})") from None
        if not self._container.streams.video:
            self._container.close()
            raise DatasetError(f"{self.path}: holds no video stream")
        stream = self._container.streams.video[0]
        # FFmpeg decodes the next frames in its own threads (no GIL) while Python tracks
        # this one: 10-25 % more frames per second end to end (docs/benchmarks.md).
        stream.thread_type = "FRAME"
        self._frames = self._container.decode(stream)

    def read(self) -> np.ndarray | None:
        """The next frame, or None after the last one."""
        if self._container is None:
            return None
        try:
            frame = next(self._frames, None)
        except (OSError, av.FFmpegError) as exc:
            raise DatasetError(f"{self.path}: cannot decode frame {self.n_read} ({exc})") from None
        if frame is None:
            self.close()
            return None
        self.n_read += 1
        image = _gray_image(frame) if self.gray else frame.to_ndarray(format="rgb24")
        return _upright(image, frame)

    def __iter__(self) -> Iterator[np.ndarray]:
        while (image := self.read()) is not None:
            yield image

    def close(self) -> None:
        """Release the file (idempotent)."""
        if self._container is not None:
            self._container.close()
            self._container = None

    def __enter__(self) -> VideoReader:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def frame_rate(path: str | Path) -> float | None:
    """The frame rate (frames/s) the container of ``path`` declares for its first video
    stream (its average rate, else FFmpeg's guess), or None when it declares none. Raises
    :class:`DatasetError` naming the file if it cannot be opened or has no video stream."""
    try:
        with av.open(str(path)) as container:
            if not container.streams.video:
                raise DatasetError(f"{path}: holds no video stream")
            stream = container.streams.video[0]
            rate = stream.average_rate or stream.guessed_rate
    except (OSError, av.FFmpegError) as exc:
        raise DatasetError(f"{path}: cannot open video ({exc})") from None
    return float(rate) if rate and float(rate) > 0 else None


def open_video_frames(paths: Sequence[str | Path], *, gray: bool = False
                      ) -> Iterator[list[np.ndarray]]:
    """Synchronised frames of several videos, one per camera (for ``digiteyes track``).

    Returns an iterator of lists holding one image per file, in the order of ``paths``
    (the order of the rig's cameras): ``uint8`` (H, W) if ``gray`` else (H, W, 3) RGB. It
    stops when the shortest video ends. Every file is opened before this function returns,
    so a missing or undecodable file raises :class:`DatasetError` naming it at once.
    """
    if not paths:
        raise DatasetError("open_video_frames needs at least one video file")
    readers: list[VideoReader] = []
    try:
        for path in paths:
            readers.append(VideoReader(path, gray=gray))
    except DatasetError:
        for reader in readers:
            reader.close()
        raise
    return _zip_frames(readers)


def _zip_frames(readers: list[VideoReader]) -> Iterator[list[np.ndarray]]:
    try:
        step = 0
        while True:
            images = [r.read() for r in readers]
            if any(im is None for im in images):
                if step == 0:
                    empty = next(r for r, im in zip(readers, images, strict=True) if im is None)
                    raise DatasetError(f"{empty.path}: video holds no frames")
                return
            step += 1
            yield images
    finally:
        for reader in readers:
            reader.close()


class CaptureReader:
    """Frames of a live camera (OpenCV ``VideoCapture``), read like :class:`VideoReader`.

    ``source`` is a camera index (``0`` the first camera) or a video file path (the same
    code path, which is how it is tested without a camera). ``read()`` returns the next
    image, ``uint8`` (H, W) if ``gray`` else (H, W, 3) RGB, or None when the camera stops.
    ``fps`` is the rate the camera or file reports (None when it reports none). Raises
    :class:`DatasetError` when the camera or file cannot be opened.
    """

    def __init__(self, source: int | str | Path, *, gray: bool = False) -> None:
        self.source = source
        self.gray = gray
        self.n_read = 0
        self._capture = cv2.VideoCapture(source if isinstance(source, int) else str(source))
        if not self._capture.isOpened():
            self._capture.release()
            what = f"camera {source}" if isinstance(source, int) else str(source)
            raise DatasetError(f"{what}: cannot be opened for capture")
        rate = float(self._capture.get(cv2.CAP_PROP_FPS))
        self.fps: float | None = rate if np.isfinite(rate) and rate > 0 else None

    def read(self) -> np.ndarray | None:
        """The next frame, or None when the camera or file has no more."""
        if self._capture is None:
            return None
        ok, frame = self._capture.read()
        if not ok:
            self.close()
            return None
        self.n_read += 1
        code = cv2.COLOR_BGR2GRAY if self.gray else cv2.COLOR_BGR2RGB
        return cv2.cvtColor(frame, code)

    def __iter__(self) -> Iterator[np.ndarray]:
        while (image := self.read()) is not None:
            yield image

    def close(self) -> None:
        """Release the camera (idempotent)."""
        if self._capture is not None:
            self._capture.release()
            self._capture = None


def open_capture_frames(source: int | str | Path, *, gray: bool = False) -> CaptureFrames:
    """One-camera frames of :class:`CaptureReader` as lists of one image, the shape of
    :func:`open_video_frames` (so ``digiteyes track --camera N`` runs the same loop); the
    iterator's ``fps`` is the reader's."""
    return CaptureFrames(CaptureReader(source, gray=gray))


class CaptureFrames:
    """Iterator of ``[image]`` lists from a :class:`CaptureReader`, which it closes at the
    end or when closed; ``fps`` is the rate the camera reports (None when unknown)."""

    def __init__(self, reader: CaptureReader) -> None:
        self._reader = reader
        self.fps = reader.fps

    def __iter__(self) -> CaptureFrames:
        return self

    def __next__(self) -> list[np.ndarray]:
        image = self._reader.read()
        if image is None:
            raise StopIteration
        return [image]

    def close(self) -> None:
        """Release the camera (idempotent)."""
        self._reader.close()
