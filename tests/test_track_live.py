"""``digiteyes track``: automatic start, recovery after loss, keypoints.csv, the JSON-lines
stream (stdout and TCP), the capture reader behind --camera, and --show without a display."""

from __future__ import annotations

import csv
import json
import shutil
import socket
import sys
import threading
import time
from collections.abc import Sequence

import cv2
import numpy as np
import pytest

from digiteyes import forward_kinematics
from digiteyes.camera import Rig, save_rig
from digiteyes.camera.mirror import mirrored_rig
from digiteyes.cli import main
from digiteyes.detect.hand_size import model_hand_length
from digiteyes.detect.mediapipe_detector import mediapipe_available
from digiteyes.io import VideoReader, VideoWriter, open_sequence, read_state_log
from digiteyes.io.video import CaptureReader, open_capture_frames
from digiteyes.kinematics import model_from_file
from digiteyes.kinematics.anatomy import FINGERS
from digiteyes.kinematics.keypoints import keypoints
from digiteyes.pipeline import run_tracker
from digiteyes.synth.options import RenderOptions
from digiteyes.synth.scenarios import build_scenario
from digiteyes.synth.views import render_views
from digiteyes.track_job import resolve_tracker
from digiteyes.trackers import TrackResult


@pytest.fixture(scope="module")
def webcam(tmp_path_factory):
    """Six rendered frames of the webcam setup (one camera, fingers curling)."""
    folder = tmp_path_factory.mktemp("seq") / "webcam"
    assert main(["render", "webcam-1cam", "-o", str(folder), "--frames", "6"]) == 0
    return folder


def truth_keypoints(seq, frames):
    """Names, world points (T, K, 3) of the model keypoints at the true states."""
    names, points = keypoints(seq.model, forward_kinematics(seq.model, seq.truth.states[frames]))
    return names, points


def test_stream_to_stdout_gives_each_frames_state_and_keypoints(webcam, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["track", str(webcam), "-o", str(out), "--stream", "-", "--frames", "4",
                 "--no-overlay", "--quiet"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    messages = [json.loads(line) for line in lines]
    assert [m["frame"] for m in messages] == [0, 1, 2, 3]
    seq = open_sequence(webcam)
    camera = seq.rig[0]
    names, world = truth_keypoints(seq, np.arange(4))
    for t, message in enumerate(messages):
        assert not message["lost"] and not message["reinitialised"]
        points = message["keypoints"][camera.name]
        assert set(points) == set(names)
        xyz = np.array([points[n]["xyz_mm"] for n in names])
        uv = np.array([points[n]["uv_px"] for n in names])
        # the tracker follows the truth within a few mm; the keypoints are in camera frame
        assert np.median(np.linalg.norm(xyz - camera.to_camera(world[t]), axis=1)) < 6.0
        assert np.median(np.linalg.norm(uv - camera.project(world[t]), axis=1)) < 6.0
        assert list(message["state"]) == list(seq.model.state_names)
    # keypoints.csv holds the same numbers under named columns
    with open(out / "keypoints.csv", newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 4
    first = names[0]
    for row, message in zip(rows, messages, strict=True):
        got = [float(row[f"{camera.name}.{first}.{a}"]) for a in ("x_mm", "y_mm", "z_mm")]
        assert np.allclose(got, message["keypoints"][camera.name][first]["xyz_mm"], atol=0.02)


def test_stream_with_smoothing_carries_the_online_filter(webcam, tmp_path, capsys):
    """``--stream - --smooth``: each line's ``state_smoothed`` is the One Euro filter run
    online, equal to the batch filter's ``states-smoothed.csv`` row; without ``--smooth``
    the lines have no smoothed fields; the first frame's smoothed state is the raw one."""
    from digiteyes.kinematics import State

    out = tmp_path / "out"
    assert main(["track", str(webcam), "-o", str(out), "--stream", "-", "--frames", "6",
                 "--no-overlay", "--quiet", "--smooth"]) == 0
    messages = [json.loads(line) for line in capsys.readouterr().out.strip().splitlines()]
    model = open_sequence(webcam).model
    smoothed = read_state_log(out / "states-smoothed.csv", model).states
    raw = read_state_log(out / "states.csv", model).states
    streamed = np.array([list(m["state_smoothed"].values()) for m in messages])
    np.testing.assert_allclose(streamed, smoothed, atol=1e-6)
    np.testing.assert_allclose(streamed[0], raw[0], atol=1e-6)
    assert np.abs(streamed[1:] - raw[1:]).max() > 1e-4
    camera = open_sequence(webcam).rig[0].name
    kin = keypoints(model, forward_kinematics(model, State(model, smoothed[-1]).q))
    assert set(messages[-1]["keypoints_smoothed"][camera]) == set(kin[0])
    assert main(["track", str(webcam), "-o", str(tmp_path / "plain"), "--stream", "-",
                 "--frames", "2", "--no-overlay", "--quiet"]) == 0
    plain = json.loads(capsys.readouterr().out.strip().splitlines()[0])
    assert "state_smoothed" not in plain and "keypoints_smoothed" not in plain


def test_stream_to_a_local_socket(webcam, tmp_path, capsys):
    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]
    received: list[bytes] = []

    def serve():
        conn, _ = server.accept()
        with conn:
            while chunk := conn.recv(65536):
                received.append(chunk)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    assert main(["track", str(webcam), "-o", str(tmp_path / "o"), "--frames", "2",
                 "--stream", f"tcp://127.0.0.1:{port}", "--no-overlay", "--quiet"]) == 0
    thread.join(timeout=10)
    server.close()
    messages = [json.loads(line) for line in b"".join(received).decode().splitlines()]
    assert [m["frame"] for m in messages] == [0, 1]
    assert "tracked 2 frame(s)" in capsys.readouterr().out


def test_bad_stream_target_is_one_line_error(webcam, tmp_path, capsys):
    assert main(["track", str(webcam), "-o", str(tmp_path / "o"), "--stream", "udp://x"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "tcp://HOST:PORT" in err[0]


def test_auto_start_reaches_the_truth_within_five_frames(webcam, tmp_path):
    out = tmp_path / "auto"
    assert main(["track", str(webcam), "-o", str(out), "--init", "auto", "--detector",
                 "classic", "--no-overlay", "--quiet"]) == 0
    seq = open_sequence(webcam)
    log = read_state_log(out / "states.csv", seq.model)
    names, est = keypoints(seq.model, forward_kinematics(seq.model, log.states))
    truth = seq.truth.keypoints_3d[log.frames][:, [seq.truth.keypoint_names.index(n)
                                                   for n in names]]
    error = np.linalg.norm(est - truth, axis=2).mean(axis=1)
    assert error[0] < 25.0  # the fit to the classic detector's keypoints
    assert error[5] < 5.0  # the tracker has pulled it onto the image
    summary = json.loads((out / "summary.json").read_text())
    assert summary["start"]["init"] == "auto" and summary["start"]["first_frame"] == 0
    assert summary["start"]["found_by"] == ["classic"]
    assert summary["reinitialisations"] == 0


class LoseAfter:
    """A test tracker: holds its state, calls the track lost from frame ``lost_from`` on
    (counted since the last reset); ``scale``: the hand's size it reports (None: it does
    not size the hand)."""

    stages = ("hold",)

    def __init__(self, lost_from: int, scale: float | None = None) -> None:
        self.lost_from = lost_from
        self.state = None
        self.frame = 0
        self.scale = scale

    def reset(self, initial_state: np.ndarray) -> None:
        self.state = np.array(initial_state, dtype=float)
        self.frame = 0

    def step(self, frames: Sequence[np.ndarray]) -> TrackResult:
        lost = self.frame >= self.lost_from
        self.frame += 1
        return TrackResult(state=self.state.copy(), cost=0.0, residual_rms_px=0.0, lost=lost,
                           loss_reason="test" if lost else "", iterations=1,
                           predicted_state=self.state.copy(), frame_index=self.frame,
                           timings={"hold": 0.0, "total": 0.0},
                           finger_lost=dict.fromkeys(FINGERS, False), details=None,
                           hand_scale=1.0 if self.scale is None else self.scale)


def test_recovery_marks_each_reinitialisation(webcam, tmp_path):
    seq = open_sequence(webcam)
    start = np.array(seq.initial_state, dtype=float)
    fresh = seq.truth.states[3].copy()
    calls = []

    def recover(images, hand_scale):
        calls.append((len(images), hand_scale))
        return fresh

    tracker = LoseAfter(lost_from=2, scale=0.9)
    run = run_tracker(tracker, seq.model, seq.rig, iter(seq), start, tmp_path / "r",
                      overlay=False, progress=False, views_every=0, warm=False,
                      recover=recover)
    # lost at frame 2; restarted there, it counts anew: frames 3, 4 held, 5 lost; the
    # re-detection is asked for a hand of the size the tracker measured
    assert run.reinitialised_frames == [2, 5] and calls == [(1, 0.9), (1, 0.9)]
    header = (tmp_path / "r" / "states.csv").read_text().splitlines()[0].split(",")
    assert "reinitialised" in header
    with open(tmp_path / "r" / "states.csv", newline="") as handle:
        flags = [int(row["reinitialised"]) for row in csv.DictReader(handle)]
    assert flags == [0, 0, 1, 0, 0, 1]
    log = read_state_log(tmp_path / "r" / "states.csv", seq.model)
    assert np.allclose(log.states[2], fresh) and np.allclose(log.states[1], start)
    assert np.allclose(log.hand_scale, 0.9)  # the re-detected frames' too
    assert json.loads((tmp_path / "r" / "summary.json").read_text())["reinitialisations"] == 2


class LoseAfterWithRestart(LoseAfter):
    """The same, with a ``restart`` that the run loop must prefer to ``reset``."""

    def __init__(self, lost_from: int) -> None:
        super().__init__(lost_from)
        self.restarts: list[np.ndarray] = []

    def restart(self, state: np.ndarray) -> None:
        self.restarts.append(np.array(state))
        self.state = np.array(state, dtype=float)
        self.frame = 0


def test_recovery_restarts_a_tracker_that_can(webcam, tmp_path):
    seq = open_sequence(webcam)
    fresh = seq.truth.states[3].copy()
    tracker = LoseAfterWithRestart(lost_from=2)
    run = run_tracker(tracker, seq.model, seq.rig, iter(seq), seq.initial_state,
                      tmp_path / "r", overlay=False, progress=False, views_every=0,
                      warm=False, recover=lambda images, hand_scale: fresh)
    assert run.reinitialised_frames == [2, 5] and len(tracker.restarts) == 2
    np.testing.assert_array_equal(tracker.restarts[0], fresh)


def test_capture_reader_reads_a_video_file_like_the_video_reader(tmp_path):
    rng = np.random.default_rng(0)
    path = tmp_path / "clip.mkv"
    frames = [rng.integers(0, 255, (48, 64, 3), dtype=np.uint8) for _ in range(3)]
    with VideoWriter(path, 15.0) as writer:
        for frame in frames:
            writer.write(frame)
    expected = list(VideoReader(path))
    reader = CaptureReader(path)
    assert reader.fps == pytest.approx(15.0)
    got = list(reader)
    assert len(got) == 3
    for a, b in zip(got, expected, strict=True):
        assert a.shape == b.shape and np.mean(np.abs(a.astype(int) - b)) < 3.0
    lists = open_capture_frames(path)
    assert lists.fps == pytest.approx(15.0)
    assert [len(images) for images in lists] == [1, 1, 1]


def test_show_without_display_says_so_and_tracks(webcam, tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    started = time.perf_counter()
    assert main(["track", str(webcam), "-o", str(tmp_path / "s"), "--show", "--frames", "2",
                 "--no-overlay", "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "--show skipped: no display" in out and "tracked 2 frame(s)" in out
    assert time.perf_counter() - started < 120


def test_auto_start_on_an_uncalibrated_video_uses_the_default_camera(webcam, tmp_path,
                                                                     capsys):
    video = tmp_path / "clip.mkv"
    seq = open_sequence(webcam)
    with VideoWriter(video, 10.0) as writer:
        for images in list(seq)[:3]:
            writer.write(images[0])
    out = tmp_path / "v"
    assert main(["track", str(video), "--init", "auto", "--detector", "classic", "-o",
                 str(out), "--no-overlay", "--quiet"]) == 0
    assert "--init auto: hand found in frame 0" in capsys.readouterr().out
    with open(out / "keypoints.csv", newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 3
    depth = float(rows[0]["camera.palm.z_mm"])  # the default camera is named "camera"
    assert 100.0 < depth < 2000.0


def test_a_hand_that_enters_late_is_found_and_numbered_as_in_the_video(webcam, tmp_path,
                                                                       capsys):
    """Three empty frames, then the hand: the start searches past them, and every output
    numbers the frames as the video does (so they line up with it and with the truth)."""
    video = tmp_path / "late.mkv"
    seq = open_sequence(webcam)
    images = [frame[0] for frame in seq]
    with VideoWriter(video, 10.0) as writer:
        for _ in range(3):
            writer.write(np.zeros_like(images[0]))
        for image in images[:3]:
            writer.write(image)
    out = tmp_path / "late"
    assert main(["track", str(video), "--init", "auto", "--detector", "classic", "-o",
                 str(out), "--no-overlay", "--quiet"]) == 0
    assert "hand found in frame 3" in capsys.readouterr().out
    log = read_state_log(out / "states.csv", seq.model)
    assert list(log.frames) == [3, 4, 5]
    with open(out / "keypoints.csv", newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert [int(row["frame"]) for row in rows] == [3, 4, 5]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["start"]["first_frame"] == 3 and summary["frames_missing"] == 0
    # the tracked tips in the image against the true ones: video frame k + 3 is truth's k
    truth = seq.truth
    for k, row in enumerate(rows):
        for finger in FINGERS:
            name = f"{finger}.tip"
            true_uv = truth.keypoints_2d[k, 0, truth.keypoint_names.index(name)]
            uv = [float(row[f"camera.{name}.u_px"]), float(row[f"camera.{name}.v_px"])]
            assert np.linalg.norm(np.subtract(uv, true_uv)) < 15.0, (k, name)


def test_the_search_for_a_hand_stops_at_init_frames(webcam, tmp_path, capsys):
    video = tmp_path / "late.mkv"
    image = next(iter(open_sequence(webcam)))[0]
    with VideoWriter(video, 10.0) as writer:
        for _ in range(3):
            writer.write(np.zeros_like(image))
        writer.write(image)
    assert main(["track", str(video), "--init", "auto", "--init-frames", "2", "--detector",
                 "classic", "-o", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no hand found in 2 frame(s)" in err[0]


def columns_of(path):
    """A CSV file's numeric columns by name."""
    with open(path, newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    return {key: np.array([float(row[key]) for row in rows]) for key in rows[0]}


def test_a_left_hand_is_tracked_as_the_mirror_image_of_a_right_one(webcam, tmp_path, capsys):
    """The rendered right hand's images flipped, with the mirrored rig, show a left hand.
    ``--hand left`` tracks it as the right hand of their mirror image, which is the
    original scene: the same track, and every output in the left hand's images."""
    seq = open_sequence(webcam)
    images = [frame[0] for frame in seq]
    width = seq.rig[0].width
    right_video, left_video = tmp_path / "right.mkv", tmp_path / "left.mkv"
    for path, flip in ((right_video, False), (left_video, True)):
        with VideoWriter(path, 10.0) as writer:  # FFV1: lossless
            for image in images:
                writer.write(image[:, ::-1] if flip else image)
    save_rig(seq.rig, tmp_path / "right-rig.json")
    save_rig(mirrored_rig(seq.rig), tmp_path / "left-rig.json")
    init = str(webcam / "initial_state.json")
    for side in ("right", "left"):
        assert main(["track", str(tmp_path / f"{side}.mkv"), "--rig",
                     str(tmp_path / f"{side}-rig.json"), "--init", init, "--hand", side,
                     "-o", str(tmp_path / side), "--quiet"]) == 0
    capsys.readouterr()
    right = read_state_log(tmp_path / "right" / "states.csv", seq.model)
    left = read_state_log(tmp_path / "left" / "states.csv", seq.model)
    np.testing.assert_allclose(left.states, right.states, atol=1e-9)

    r, l_ = (columns_of(tmp_path / side / "keypoints.csv") for side in ("right", "left"))
    for key in r:
        if key.endswith(".u_px"):
            np.testing.assert_allclose(l_[key], width - 1 - r[key], atol=1e-6)
        elif key.endswith(".x_mm"):
            np.testing.assert_allclose(l_[key], -r[key], atol=1e-6)
        else:
            np.testing.assert_allclose(l_[key], r[key], atol=1e-6)
    # the overlay is drawn over the left hand's own images
    with VideoReader(tmp_path / "right" / "overlay.mp4") as a, \
            VideoReader(tmp_path / "left" / "overlay.mp4") as b:
        first_right, first_left = a.read(), b.read()
    assert np.abs(first_left.astype(int) - first_right[:, ::-1].astype(int)).mean() < 2.0
    # the 3D views show the left hand: the right run's picture flipped
    for name in sorted(p.name for p in (tmp_path / "right" / "views").glob("*.png")):
        right_view, left_view = (cv2.imread(str(tmp_path / side / "views" / name))
                                 for side in ("right", "left"))
        np.testing.assert_array_equal(left_view, right_view[:, ::-1])
    # `export` reads the side from summary.json: the left hand's 3D keypoints, x -> -x
    for side in ("right", "left"):
        assert main(["export", str(tmp_path / side), "-o", str(tmp_path / f"{side}-x"),
                     "--format", "csv"]) == 0
    assert "a left hand" in capsys.readouterr().out
    right_table, left_table = (columns_of(tmp_path / f"{side}-x" / "track.csv")
                               for side in ("right", "left"))
    np.testing.assert_allclose(left_table["index.tip_x_mm"], -right_table["index.tip_x_mm"],
                               atol=1e-6)
    np.testing.assert_allclose(left_table["index.tip_z_mm"], right_table["index.tip_z_mm"],
                               atol=1e-6)


def test_large_images_are_tracked_at_the_working_size_with_outputs_in_their_pixels(
        webcam, tmp_path, capsys):
    """``--max-size 480`` on the 640x480 render: tracked at 480x360 with the resized
    camera, the keypoints reported in the 640x480 images, on the true ones."""
    seq = open_sequence(webcam)
    out = tmp_path / "small"
    assert main(["track", str(webcam), "--max-size", "480", "-o", str(out), "--quiet"]) == 0
    assert "tracking at 480x360 (images 640x480" in capsys.readouterr().out
    assert json.loads((out / "summary.json").read_text())["start"]["working_size"] == [480, 360]
    with open(out / "keypoints.csv", newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    truth, camera = seq.truth, seq.rig[0].name
    errors = [np.linalg.norm(np.subtract(
        [float(row[f"{camera}.{name}.u_px"]), float(row[f"{camera}.{name}.v_px"])],
        truth.keypoints_2d[k, 0, truth.keypoint_names.index(name)]))
        for k, row in enumerate(rows) for name in (f"{f}.tip" for f in FINGERS)]
    assert np.mean(errors) < 6.0
    with VideoReader(out / "overlay.mp4") as reader:
        assert reader.read().shape[:2] == (360, 480)  # drawn at the working size


def test_a_video_without_init_starts_from_its_images(webcam, tmp_path, capsys):
    """No --init for footage means --init auto; a video without a hand is then a
    one-line error that says what to give."""
    video = tmp_path / "clip.mkv"
    first = next(iter(open_sequence(webcam)))[0]
    with VideoWriter(video, 10.0) as writer:
        writer.write(first)
    assert main(["track", str(video), "--detector", "classic", "-o", str(tmp_path / "o"),
                 "--quiet", "--no-overlay"]) == 0
    assert "--init auto: hand found in frame 0" in capsys.readouterr().out
    blank = tmp_path / "blank.mkv"
    with VideoWriter(blank, 10.0) as writer:
        writer.write(np.zeros_like(first))
    assert main(["track", str(blank), "--detector", "classic", "-o",
                 str(tmp_path / "b"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no hand found" in err[0] and "--init FILE" in err[0]


class _Mismatch:
    """A silhouette rule that scores the estimate and a re-detection as told."""

    def __init__(self, fresh: np.ndarray, estimate_score: float, fresh_score: float) -> None:
        self.fresh, self.scores = fresh, (estimate_score, fresh_score)

    def mismatch(self, images, state, colours=None):
        return self.scores[1] if np.array_equal(state, self.fresh) else self.scores[0]


@pytest.mark.parametrize("fresh_score, accepted", [(0.1, True), (0.5, False), (0.9, False)])
def test_recovery_keeps_the_track_when_the_redetection_explains_less(webcam, tmp_path,
                                                                      fresh_score, accepted):
    """A re-detection replaces the estimate only when it explains the hand's silhouette
    better (``recovered_state``); a worse or equal one is declined and the tracker goes on
    from its estimate."""
    seq = open_sequence(webcam)
    fresh = seq.truth.states[3].copy()
    tracker = LoseAfter(lost_from=2)
    tracker.silhouette_loss = _Mismatch(fresh, 0.5, fresh_score)
    run = run_tracker(tracker, seq.model, seq.rig, iter(seq), seq.initial_state,
                      tmp_path / "r", overlay=False, progress=False, views_every=0,
                      warm=False, recover=lambda images, hand_scale: fresh)
    # after the restart at frame 2 the estimate is the re-detected state itself, so the
    # same re-detection at the next loss (frame 5) explains no more and is declined
    assert run.reinitialised_frames == ([2] if accepted else [])
    log = read_state_log(tmp_path / "r" / "states.csv", seq.model)
    assert np.allclose(log.states[2], fresh) == accepted


@pytest.mark.parametrize(("footage", "detector", "available", "expected"), [
    (True, "auto", True, "keypoints"),
    (True, "mediapipe-lite", True, "keypoints"),
    (True, "classic", True, "features"),
    (True, "auto", False, "features"),
    (False, "auto", True, "features"),
])
def test_the_auto_tracker_is_the_keypoint_tracker_for_footage_with_a_learned_detector(
        monkeypatch, footage, detector, available, expected):
    """Footage: the keypoint tracker; a dataset: the feature tracker, anchored by the
    keypoints when the detector sees its hand where the start is."""
    import digiteyes.detect.mediapipe_detector as mediapipe_detector

    monkeypatch.setattr(mediapipe_detector, "mediapipe_available", lambda: available)
    assert resolve_tracker("auto", footage, detector) == expected
    anchored = "features+keypoints" if available and detector != "classic" else "features"
    assert resolve_tracker("auto", False, detector, detector_agrees=lambda: True) == anchored
    assert resolve_tracker("templates", footage, detector) == "templates"


def flesh_video(folder, n_frames, mirrored=False):
    """Camera 0 of the desk setup, the flesh hand's colour views (truth inside) and the
    video of them (flipped left to right when ``mirrored``: a left hand)."""
    scenario = build_scenario("desk-2cam", seed=0, n_frames=n_frames)
    camera = scenario.rig[0]
    views = [render_views(scenario.model, q, [camera], RenderOptions(appearance="flesh",
                                                                    color=True), rng=k)[0]
             for k, q in enumerate(scenario.states)]
    video = folder / ("left.mkv" if mirrored else "flesh.mkv")
    with VideoWriter(video, 10.0) as writer:
        for view in views:
            writer.write(view.image[:, ::-1] if mirrored else view.image)
    return camera, views, video


def tip_errors_px(out, camera, views) -> list[float]:
    """Per frame of ``keypoints.csv`` in ``out`` and finger, the distance (px) of the
    tracked fingertip in ``camera`` from the true one of ``views``."""
    with open(out / "keypoints.csv", newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    return [float(np.linalg.norm(np.subtract(
        [float(row[f"{camera.name}.{f}.tip.u_px"]), float(row[f"{camera.name}.{f}.tip.v_px"])],
        views[k].keypoints_2d[views[k].keypoint_names.index(f"{f}.tip")])))
        for k, row in enumerate(rows) for f in FINGERS]


@pytest.mark.skipif(not mediapipe_available(), reason="optional extra digiteyes[mediapipe]")
def test_a_colour_video_of_the_flesh_hand_is_tracked_by_the_keypoint_tracker(tmp_path, capsys):
    """``track VIDEO --init auto`` with the extra: the keypoint tracker, on the hand."""
    camera, views, video = flesh_video(tmp_path, 6)
    save_rig(Rig((camera,)), tmp_path / "rig.json")
    out = tmp_path / "out"
    assert main(["track", str(video), "--rig", str(tmp_path / "rig.json"), "--init", "auto",
                 "-o", str(out), "--quiet"]) == 0
    assert "tracker: keypoints" in capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert summary["tracker"] == "keypoints" and summary["lost_frames"] == 0
    errors = tip_errors_px(out, camera, views)
    assert np.median(errors) < 12.0


@pytest.mark.skipif(not mediapipe_available(), reason="optional extra digiteyes[mediapipe]")
def test_a_colour_video_is_tracked_by_features_anchored_by_keypoints(tmp_path):
    """``track VIDEO --init auto --tracker features+keypoints``: on the hand, and without
    the detection check that other trackers get on footage (it detects every frame)."""
    camera, views, video = flesh_video(tmp_path, 6)
    save_rig(Rig((camera,)), tmp_path / "rig.json")
    out = tmp_path / "out"
    assert main(["track", str(video), "--rig", str(tmp_path / "rig.json"), "--init", "auto",
                 "--tracker", "features+keypoints", "-o", str(out), "--quiet",
                 "--no-overlay"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["tracker"] == "features+keypoints" and "detection_check" not in summary
    errors = tip_errors_px(out, camera, views)
    assert len(errors) == 6 * len(FINGERS) and np.median(errors) < 12.0


def test_footage_without_the_extra_says_what_it_costs_and_how_to_install(tmp_path, capsys,
                                                                        monkeypatch):
    """Without MediaPipe, ``--tracker auto`` on a video runs the feature tracker and says
    why, what that costs on real footage and how to install the extra."""
    monkeypatch.setitem(sys.modules, "mediapipe", None)  # import fails as if absent
    camera, _, video = flesh_video(tmp_path, 2)
    save_rig(Rig((camera,)), tmp_path / "rig.json")
    assert main(["track", str(video), "--rig", str(tmp_path / "rig.json"), "-o",
                 str(tmp_path / "out"), "--quiet", "--no-overlay"]) == 0
    printed = capsys.readouterr().out
    assert "tracker: features (--tracker auto: MediaPipe is not installed" in printed
    assert 'pip install "digiteyes[mediapipe]"' in printed


@pytest.mark.skipif(not mediapipe_available(), reason="optional extra digiteyes[mediapipe]")
def test_auto_takes_the_anchored_tracker_only_for_datasets_the_detector_sees(tmp_path,
                                                                            capsys):
    """A rendered flesh hand: MediaPipe finds it where the dataset starts, so the feature
    tracker anchored by its keypoints; the same images with a start 150 mm to the side of
    the hand: it does not, so the feature tracker. The keypoint tracker, asked for by
    name, measures the hand's size on-line."""
    data = tmp_path / "flesh"
    assert main(["render", "desk-2cam", "-o", str(data), "--frames", "2",
                 "--appearance", "flesh"]) == 0
    elsewhere = tmp_path / "elsewhere"
    shutil.copytree(data, elsewhere)
    start = json.loads((elsewhere / "initial_state.json").read_text())
    start["state"]["palm.x"] += 150.0
    (elsewhere / "initial_state.json").write_text(json.dumps(start))
    cases = ((data, "auto", "features+keypoints"), (data, "keypoints", "keypoints"),
             (elsewhere, "auto", "features"))
    for dataset, asked, expected in cases:
        out = tmp_path / f"{dataset.name}-{asked}-track"
        assert main(["track", str(dataset), "-o", str(out), "--tracker", asked, "--quiet",
                     "--no-overlay"]) == 0
        printed = capsys.readouterr().out
        assert (f"tracker: {expected}" in printed) is (asked == "auto")
        summary = json.loads((out / "summary.json").read_text())
        assert summary["tracker"] == expected
        # every tracker records the hand's scale (the keypoint tracker with two cameras:
        # the model's size at the start, then measured on-line; the feature trackers:
        # measured at the dataset's start, the model's size here), per frame in states.csv
        assert summary["start"].get("hand_scale") == 1.0
        header = (out / "states.csv").read_text().splitlines()[0].split(",")
        assert "hand_scale" in header
        # the model it ran with, beside the log, for export and replay
        assert model_from_file(out / "model.dh").state_names == tuple(header[
            len(header) - len(open_sequence(data).model.state_names):])
        if expected == "keypoints":
            log = read_state_log(out / "states.csv", open_sequence(data).model)
            assert summary["hand_scale"] == log.hand_scale[-1]
            assert 0.8 < summary["hand_scale"] < 1.2
            # the measured hand as a model file, for later footage of one camera
            measured = model_from_file(out / "hand-measured.dh")
            model = open_sequence(data).model
            assert measured.state_names == model.state_names
            assert model_hand_length(measured) == pytest.approx(
                summary["hand_scale"] * model_hand_length(model), rel=1e-4)
            assert "hand-measured.dh" in printed
        else:  # measured at the model's size: no personal model written
            assert summary["hand_scale"] == 1.0
            assert not (out / "hand-measured.dh").exists()


@pytest.mark.skipif(not mediapipe_available(), reason="optional extra digiteyes[mediapipe]")
def test_two_cameras_start_automatically_at_the_hands_size(tmp_path, capsys, monkeypatch):
    """A flesh hand 0.9 times the model's size before two cameras, ``--init auto``: the
    start measures the size (within 0.03), the feature tracker tracks a model of that size
    (``model.dh`` beside the log), ``hand-measured.dh`` keeps it for later footage, and
    the tracked keypoints are closer to the truth than in the same run held at the model's
    size."""
    from digiteyes.detect import initialiser
    from digiteyes.kinematics.keypoints import hand_keypoints

    data = tmp_path / "data"
    assert main(["render", "desk-2cam", "-o", str(data), "--frames", "3", "--appearance",
                 "flesh", "--color", "--noise", "2", "--hand-scale", "0.9"]) == 0
    sequence = open_sequence(data)
    errors = {}
    for sized in (True, False):
        if not sized:  # no size ever differs enough from the model's to be taken
            monkeypatch.setattr(initialiser, "MIN_SIZE_CHANGE", 1.0)
        out = tmp_path / f"track-{sized}"
        assert main(["track", str(data), "-o", str(out), "--init", "auto", "--tracker",
                     "features", "--quiet", "--no-overlay"]) == 0
        printed = capsys.readouterr().out
        summary = json.loads((out / "summary.json").read_text())
        tracked = model_from_file(out / "model.dh")
        log = read_state_log(out / "states.csv", tracked)
        names, points = hand_keypoints(tracked, log.states, log.hand_scale)
        idx = [sequence.truth.keypoint_names.index(n) for n in names]
        errors[sized] = float(np.linalg.norm(
            points - sequence.truth.keypoints_3d[:, idx], axis=2).mean())
        if not sized:
            assert "two_camera_hand_scale" not in summary["start"]
            assert not (out / "hand-measured.dh").exists()
            break
        scale = summary["start"]["two_camera_hand_scale"]
        assert scale == pytest.approx(0.9, abs=0.03)
        assert "the cameras measure the hand 0.9" in printed
        assert model_hand_length(tracked) == pytest.approx(
            scale * model_hand_length(sequence.model), rel=1e-6)
        measured = model_from_file(out / "hand-measured.dh")
        assert model_hand_length(measured) == pytest.approx(model_hand_length(tracked))
    assert errors[True] < errors[False] - 2.0, errors


@pytest.mark.skipif(not mediapipe_available(), reason="optional extra digiteyes[mediapipe]")
def test_hand_auto_tracks_a_left_hand_video_as_the_mirror_image(tmp_path, capsys):
    """The flesh hand's colour video flipped shows a left hand: with the default --hand
    auto MediaPipe says so at the start, the run mirrors itself, and the keypoints land
    on the left hand in the real images."""
    camera, views, video = flesh_video(tmp_path, 5, mirrored=True)
    save_rig(mirrored_rig(Rig((camera,))), tmp_path / "rig.json")
    out = tmp_path / "out"
    assert main(["track", str(video), "--rig", str(tmp_path / "rig.json"), "--init", "auto",
                 "-o", str(out), "--quiet", "--no-overlay"]) == 0
    assert "--hand auto: the detector sees a left hand" in capsys.readouterr().out
    start = json.loads((out / "summary.json").read_text())["start"]
    assert start["hand"] == "left"
    assert start["hand_scale"] == 1.0  # footage: the model's size, none read from the start
    with open(out / "keypoints.csv", newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    errors = []
    for k, row in enumerate(rows):
        for f in FINGERS:
            u, v = views[k].keypoints_2d[views[k].keypoint_names.index(f"{f}.tip")]
            tracked = [float(row[f"{camera.name}.{f}.tip.u_px"]),
                       float(row[f"{camera.name}.{f}.tip.v_px"])]
            errors.append(np.linalg.norm(np.subtract(tracked, [camera.width - 1 - u, v])))
    assert np.median(errors) < 12.0


def test_a_folder_of_images_is_tracked_like_a_video(webcam, tmp_path, capsys):
    """Numbered frames in a folder (natural order: frame_2 before frame_10), read as
    footage; a folder with neither images nor sequence.json is a one-line error."""
    seq = open_sequence(webcam)
    folder = tmp_path / "frames"
    folder.mkdir()
    images = [frame[0] for frame in seq]
    for k, image in enumerate(images):  # written out of order, numbered without padding
        cv2.imwrite(str(folder / f"frame_{k * 5}.png"), image)
    out = tmp_path / "out"
    assert main(["track", str(folder), "--init", "auto", "--detector", "classic",
                 "--fps", "10", "-o", str(out), "--quiet", "--no-overlay"]) == 0
    with open(out / "keypoints.csv", newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert [int(r["frame"]) for r in rows] == list(range(len(images)))
    truth = seq.truth
    for k, row in enumerate(rows):  # frame k is image k: the order was kept
        u, v = truth.keypoints_2d[k, 0, truth.keypoint_names.index("index.tip")]
        assert np.hypot(float(row["camera.index.tip.u_px"]) - u,
                        float(row["camera.index.tip.v_px"]) - v) < 15.0
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "notes.txt").write_text("no images here")
    capsys.readouterr()
    assert main(["track", str(empty), "--init", "auto", "-o", str(tmp_path / "o")]) == 2
    assert "sequence.json" in capsys.readouterr().err


@pytest.mark.skipif(not mediapipe_available(), reason="optional extra digiteyes[mediapipe]")
def test_the_detector_must_see_the_hand_in_the_first_frames_not_only_the_first():
    """``--tracker auto`` on a dataset: our capsule drawing of the desk view passes the
    first frame (MediaPipe puts every digit within 0.22 palm lengths of the start) but
    MediaPipe loses it in later frames, so the feature tracker; a flesh hand 0.9 times
    the model's size, which the first frame's old bound refused (its thumb), is the
    keypoint tracker's."""
    from digiteyes.benchmarks.tracker import render_sequence
    from digiteyes.synth.setups import setup_scenario
    from digiteyes.track_job import AGREEMENT_FRAMES, _detector_agrees

    cases = ((setup_scenario("desk", 2, seed=0, n_frames=AGREEMENT_FRAMES), "model", False),
             (setup_scenario("desk", 2, hand_scale=0.9, seed=0, n_frames=AGREEMENT_FRAMES),
              "flesh", True))
    for scenario, appearance, expected in cases:
        sequence = render_sequence(scenario, seed=0, appearance=appearance, color=True)
        assert _detector_agrees(scenario.model, sequence.rig, "auto",
                                list(sequence.images), scenario.states[0]) is expected
