"""Video files: lossless FFV1 round trip, synchronised multi-camera reading, bad files."""

from __future__ import annotations

import struct

import av
import cv2
import numpy as np
import pytest

from digiteyes.errors import DatasetError
from digiteyes.io import VideoReader, VideoWriter, open_video_frames


def write_video(path, images, codec="ffv1"):
    with VideoWriter(path, 30, codec) as writer:
        for image in images:
            writer.write(image)


def test_ffv1_is_lossless_for_grey_and_rgb(tmp_path):
    rng = np.random.default_rng(2)
    grey = [rng.integers(0, 256, (30, 40), dtype=np.uint8) for _ in range(3)]
    rgb = [rng.integers(0, 256, (30, 40, 3), dtype=np.uint8) for _ in range(3)]
    write_video(tmp_path / "g.mkv", grey)
    write_video(tmp_path / "c.mkv", rgb)
    with VideoReader(tmp_path / "g.mkv", gray=True) as reader:
        for got, want in zip(reader, grey, strict=True):
            np.testing.assert_array_equal(got, want)
    with VideoReader(tmp_path / "c.mkv") as reader:
        frames = list(reader)
        assert reader.n_read == 3
    for got, want in zip(frames, rgb, strict=True):
        np.testing.assert_array_equal(got, want)


def test_open_video_frames_stops_at_shortest(tmp_path):
    rng = np.random.default_rng(3)
    a = [rng.integers(0, 256, (16, 16, 3), dtype=np.uint8) for _ in range(5)]
    b = [rng.integers(0, 256, (16, 16, 3), dtype=np.uint8) for _ in range(4)]
    write_video(tmp_path / "a.mkv", a)
    write_video(tmp_path / "b.mkv", b)
    steps = list(open_video_frames([tmp_path / "a.mkv", tmp_path / "b.mkv"]))
    assert len(steps) == 4
    for i, (img_a, img_b) in enumerate(steps):
        np.testing.assert_array_equal(img_a, a[i])
        np.testing.assert_array_equal(img_b, b[i])
    grey = next(open_video_frames([tmp_path / "a.mkv"], gray=True))[0]
    assert grey.shape == (16, 16) and grey.dtype == np.uint8


def test_missing_or_undecodable_video_is_named(tmp_path):
    write_video(tmp_path / "ok.mkv", [np.zeros((8, 8), np.uint8)])
    (tmp_path / "junk.mp4").write_bytes(b"this is not a video" * 50)
    with pytest.raises(DatasetError, match=r"nothere\.mp4"):
        open_video_frames([tmp_path / "ok.mkv", tmp_path / "nothere.mp4"])
    with pytest.raises(DatasetError, match=r"junk\.mp4"):
        open_video_frames([tmp_path / "junk.mp4"])


def test_writer_rejects_bad_frames(tmp_path):
    writer = VideoWriter(tmp_path / "x.mp4", 30, "h264")
    with pytest.raises(DatasetError, match="even image sizes"):
        writer.write(np.zeros((9, 8), np.uint8))
    writer = VideoWriter(tmp_path / "y.mkv", 30)
    writer.write(np.zeros((8, 8), np.uint8))
    with pytest.raises(DatasetError, match="shape"):
        writer.write(np.zeros((8, 10), np.uint8))
    with pytest.raises(DatasetError, match="uint8"):
        writer.write(np.zeros((8, 8), np.float32))
    writer.close()
    with pytest.raises(DatasetError, match="unknown video codec"):
        VideoWriter(tmp_path / "z.avi", 30, "divx")


def test_h264_crf_trades_size_for_fidelity(tmp_path):
    """A noisy smooth image: the near-lossless default keeps the noise (bigger file, small
    error), x264's default CRF 23 smooths it away (much smaller file, larger error)."""
    rng = np.random.default_rng(4)
    ramp = np.add.outer(np.arange(64.0), np.arange(96.0))
    images = [np.clip(ramp + 60 + rng.normal(0, 3, ramp.shape), 0, 255).astype(np.uint8)
              for _ in range(6)]
    errors, sizes = {}, {}
    for crf in (12, 23):
        path = tmp_path / f"crf{crf}.mp4"
        with VideoWriter(path, 30, "h264", crf=crf) as writer:
            for image in images:
                writer.write(image)
        with VideoReader(path, gray=True) as reader:
            errors[crf] = np.mean([np.abs(got.astype(float) - want).mean()
                                   for got, want in zip(reader, images, strict=True)])
        sizes[crf] = path.stat().st_size
    assert sizes[23] < 0.5 * sizes[12]
    assert errors[12] < 1.9 < errors[23]
    for bad in (-1, 52, 2.5, True):
        with pytest.raises(DatasetError, match="crf"):
            VideoWriter(tmp_path / "bad.mp4", 30, "h264", crf=bad)
    with pytest.raises(DatasetError, match="preset"):
        VideoWriter(tmp_path / "bad.mp4", 30, "h264", preset="warp")


def _encode_yuv(path, images, encoder, pix_fmt):
    """Encode grey images with FFmpeg's own grey -> YUV conversion (as cameras deliver)."""
    with av.open(str(path), "w") as container:
        stream = container.add_stream(encoder, rate=30)
        stream.width, stream.height, stream.pix_fmt = images[0].shape[1], images[0].shape[0], \
            pix_fmt
        for image in images:
            frame = av.VideoFrame.from_ndarray(image, format="gray").reformat(format=pix_fmt)
            container.mux(stream.encode(frame))
        container.mux(stream.encode())


@pytest.mark.parametrize(("encoder", "pix_fmt", "suffix"),
                         [("libx264", "yuv420p", ".mp4"), ("mjpeg", "yuvj420p", ".avi")])
def test_grey_from_luma_plane_matches_ffmpeg_conversion(tmp_path, encoder, pix_fmt, suffix):
    # Limited-range (x264) and full-range (webcam MJPEG) luma must both come out as
    # FFmpeg's own YUV -> grey conversion would give them.
    rng = np.random.default_rng(4)
    ramp = np.linspace(0, 255, 64)[None, :] + np.zeros((48, 1))
    images = [np.clip(ramp + rng.normal(0, 20, ramp.shape), 0, 255).astype(np.uint8)
              for _ in range(3)]
    path = tmp_path / f"clip{suffix}"
    _encode_yuv(path, images, encoder, pix_fmt)
    with av.open(str(path)) as container:
        want = [f.to_ndarray(format="gray") for f in container.decode(video=0)]
    with VideoReader(path, gray=True) as reader:
        got = list(reader)
    assert len(got) == len(want) == 3
    for g, w in zip(got, want, strict=True):
        assert g.shape == w.shape and g.dtype == np.uint8
        assert np.abs(g.astype(int) - w).max() <= 1
        assert w.max() - w.min() > 200  # the full grey range survived


@pytest.mark.parametrize("fps, codec, suffix", [(25, "ffv1", ".mkv"), (29.97, "h264", ".mp4"),
                                                (12, "ffv1", ".mkv")])
def test_frame_rate_is_what_the_writer_declared(tmp_path, fps, codec, suffix):
    from digiteyes.io.video import frame_rate

    path = tmp_path / f"clip{suffix}"
    with VideoWriter(path, fps, codec=codec) as writer:
        for i in range(4):
            writer.write(np.full((48, 64), 40 * i, np.uint8))
    assert frame_rate(path) == pytest.approx(fps, rel=1e-3)
    broken = tmp_path / "broken.mp4"
    broken.write_bytes(b"not a video")
    with pytest.raises(DatasetError, match=r"broken\.mp4"):
        frame_rate(broken)


def _set_display_rotation(path, a, b, c, d):
    """Write the 2x2 part of the MP4 track header's display matrix (16.16 fixed point), as
    a phone does for a portrait recording: the frames stay landscape."""
    data = bytearray(path.read_bytes())
    # tkhd (version 0): type, version+flags, 2 times, id, reserved, duration, 8 reserved,
    # layer, group, volume, reserved, then the 3x3 matrix
    start = data.index(b"tkhd") + 4 + 4 + 20 + 8 + 8
    one = 1 << 16
    assert struct.unpack(">9i", data[start:start + 36]) == (one, 0, 0, 0, one, 0, 0, 0,
                                                             1 << 30)
    data[start:start + 36] = struct.pack(">9i", a * one, b * one, 0, c * one, d * one, 0,
                                         0, 0, 1 << 30)
    path.write_bytes(bytes(data))


@pytest.mark.parametrize("matrix", [(0, 1, -1, 0), (0, -1, 1, 0), (-1, 0, 0, -1)])
@pytest.mark.parametrize("gray", [False, True])
def test_a_phones_display_rotation_is_applied_as_opencv_applies_it(tmp_path, matrix, gray):
    """A portrait phone video (landscape frames plus a display rotation) reads upright:
    the same pictures as OpenCV's reader, which applies the rotation itself."""
    image = np.full((48, 64, 3), 40, np.uint8)
    image[4:16, 6:30] = 230  # a bright patch near the top-left corner
    path = tmp_path / "phone.mp4"
    write_video(path, [image] * 2, codec="h264")
    _set_display_rotation(path, *matrix)
    with VideoReader(path, gray=gray) as reader:
        ours = list(reader)
    capture = cv2.VideoCapture(str(path))
    ok, theirs = capture.read()
    capture.release()
    assert ok
    theirs = cv2.cvtColor(theirs, cv2.COLOR_BGR2GRAY if gray else cv2.COLOR_BGR2RGB)
    assert ours[0].shape[:2] == ((48, 64) if matrix == (-1, 0, 0, -1) else (64, 48))
    assert ours[0].shape == theirs.shape
    assert np.abs(ours[0].astype(int) - theirs.astype(int)).mean() < 3.0
