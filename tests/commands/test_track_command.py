"""``digiteyes track``, ``demo`` and ``model``: end to end through the CLI, against truth."""

from __future__ import annotations

import json

import numpy as np
import pytest

from digiteyes.cli import main
from digiteyes.io import VideoWriter, open_sequence, read_state_log
from digiteyes.kinematics import State, load_model
from digiteyes.pipeline import run_tracker
from digiteyes.trackers import FeatureTracker


def one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("digiteyes: error:"), err
    return err[0]


@pytest.fixture(scope="module")
def whole_hand(tmp_path_factory):
    """Six rendered frames of the whole-hand scenario (two cameras)."""
    folder = tmp_path_factory.mktemp("seq") / "wh"
    assert main(["render", "whole-hand", "-o", str(folder), "--frames", "6"]) == 0
    return folder


def test_track_dataset_writes_log_overlay_views_and_plots(whole_hand, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["track", str(whole_hand), "-o", str(out), "--quiet"]) == 0
    seq = open_sequence(whole_hand)
    log = read_state_log(out / "states.csv", seq.model)
    assert list(log.frames) == list(range(6)) and not log.lost.any()
    tips = [i for i, n in enumerate(seq.truth.keypoint_names) if n.endswith(".tip")]
    from digiteyes import forward_kinematics
    from digiteyes.kinematics.keypoints import keypoints

    estimated = keypoints(seq.model, forward_kinematics(seq.model, log.states))[1]
    error = np.linalg.norm(estimated[:, tips] - seq.truth.keypoints_3d[:, tips], axis=-1)
    assert error.mean() < 5.0, f"fingertip error {error.mean():.2f} mm"
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames"] == 6 and summary["lost_frames"] == 0
    assert summary["residual_unit"] == "px"
    assert summary["ms_per_iteration"] > 0
    for name in ("overlay.mp4", "trajectory-palm.png", "trajectory-joints.png",
                 "views/estimate-000005.png"):
        assert (out / name).stat().st_size > 1000, name
    assert "tracked 6 frame(s)" in capsys.readouterr().out


def test_track_smooth_writes_the_filtered_log_and_records_its_settings(whole_hand,
                                                                        tmp_path):
    """``--smooth --beta 0.3``: ``states-smoothed.csv`` is the library's filter of
    ``states.csv`` at the dataset's frame rate, and ``summary.json`` says which settings."""
    from digiteyes.filters import OneEuroOptions, one_euro_filter

    out = tmp_path / "out"
    assert main(["track", str(whole_hand), "-o", str(out), "--quiet", "--no-overlay",
                 "--smooth", "--beta", "0.3"]) == 0
    model = open_sequence(whole_hand).model
    summary = json.loads((out / "summary.json").read_text())
    settings = summary["smoothing"]
    assert settings["beta_per_mm_s"] == 0.3
    assert settings["min_cutoff_hz"] == OneEuroOptions().min_cutoff_hz
    raw = read_state_log(out / "states.csv", model)
    smoothed = read_state_log(out / "states-smoothed.csv", model)
    expected = one_euro_filter(model, raw.states, settings["fps"],
                               OneEuroOptions(beta_per_mm_s=0.3))
    np.testing.assert_allclose(smoothed.states, expected, atol=1e-6)
    assert np.abs(smoothed.states[1:] - raw.states[1:]).max() > 1e-4


def test_track_says_compiling_only_when_its_tracker_has_cold_kernels(whole_hand, tmp_path,
                                                                   capsys, monkeypatch):
    """The default tracker asks about the kernels it uses (the demo's), not every kernel of
    the package: with those compiled, ``track`` does not claim to compile."""
    import digiteyes.commands.track as track_command
    from digiteyes.warmup import COMPILE_MESSAGE, DEMO_KERNELS

    asked = []

    def cold(modules=None, only=None):
        asked.append(only)
        return [] if only is not None else ["digiteyes.smc._kernels.unused"]

    monkeypatch.setattr(track_command, "cold_kernels", cold)
    assert main(["track", str(whole_hand), "-o", str(tmp_path / "a"), "--quiet",
                 "--frames", "2", "--no-overlay"]) == 0
    assert asked == [DEMO_KERNELS] and COMPILE_MESSAGE not in capsys.readouterr().out


def write_videos(seq, folder) -> list[str]:
    """One lossless video per camera of ``seq`` and its initial state as
    ``folder/init.json``; the videos' paths."""
    videos = []
    for c, name in enumerate(seq.camera_names):
        path = folder / f"{name}.mkv"
        with VideoWriter(path, seq.fps, codec="ffv1") as writer:
            for images in seq:
                writer.write(images[c])
        videos.append(str(path))
    State(seq.model, seq.initial_state).save_json(folder / "init.json")
    return videos


def test_track_videos_matches_tracking_the_dataset(whole_hand, tmp_path):
    seq = open_sequence(whole_hand)
    videos = write_videos(seq, tmp_path)
    out = tmp_path / "video-out"
    assert main(["track", *videos, "--tracker", "features", "--model",
                 str(whole_hand / "model.dh"), "--rig", str(whole_hand / "rig.json"),
                 "--init", str(tmp_path / "init.json"),
                 "-o", str(out), "--quiet", "--no-overlay"]) == 0
    from_video = read_state_log(out / "states.csv", seq.model).states
    reference = tmp_path / "ref"
    assert main(["track", str(whole_hand), "-o", str(reference), "--quiet",
                 "--no-overlay"]) == 0
    from_dataset = read_state_log(reference / "states.csv", seq.model).states
    np.testing.assert_allclose(from_video, from_dataset, atol=1e-9)
    plain = tmp_path / "plain"
    assert main(["track", str(whole_hand), "-o", str(plain), "--quiet", "--no-overlay",
                 "--no-shading"]) == 0
    unshaded = read_state_log(plain / "states.csv", seq.model).states
    # the shading correction moves the estimate (states in mm and rad), by a little
    assert 1e-6 < np.abs(unshaded - from_dataset).max() < 5.0


def test_track_videos_takes_the_frame_rate_the_files_declare(whole_hand, tmp_path, capsys):
    """Videos at 25 and 24 frames/s: the run uses the first camera's 25 (summary, state
    log times) and warns that the rates differ; ``--fps`` overrides it."""
    seq = open_sequence(whole_hand)
    videos = []
    for c, (name, fps) in enumerate(zip(seq.camera_names, (25, 24), strict=True)):
        path = tmp_path / f"{name}.mkv"
        with VideoWriter(path, fps, codec="ffv1") as writer:
            for images in list(seq)[:3]:
                writer.write(images[c])
        videos.append(str(path))
    args = ["track", *videos, "--model", str(whole_hand / "model.dh"), "--rig",
            str(whole_hand / "rig.json"), "--init", str(whole_hand / "initial_state.json"),
            "--quiet", "--no-overlay"]
    assert main([*args, "-o", str(tmp_path / "a")]) == 0
    assert json.loads((tmp_path / "a" / "summary.json").read_text())["fps"] == 25.0
    assert "different frame rates" in capsys.readouterr().err
    assert main([*args, "-o", str(tmp_path / "b"), "--fps", "12"]) == 0
    assert json.loads((tmp_path / "b" / "summary.json").read_text())["fps"] == 12.0


def test_track_refuses_bad_input_in_one_line(whole_hand, tmp_path, capsys):
    other = tmp_path / "two-finger.json"
    State(load_model("two-finger")).save_json(other)
    assert main(["track", str(whole_hand), "--init", str(other), "-o", str(tmp_path / "a"),
                 "--quiet"]) == 2
    assert "two-finger" in one_line_error(capsys)
    video = tmp_path / "one.mkv"
    with VideoWriter(video, 10, codec="ffv1") as writer:
        writer.write(np.zeros((480, 640), np.uint8))
    assert main(["track", str(video), "--model", "hand", "--rig",
                 str(whole_hand / "rig.json"), "--init", str(whole_hand / "initial_state.json"),
                 "-o", str(tmp_path / "b"), "--quiet"]) == 2
    assert "2 camera(s)" in one_line_error(capsys)
    broken = tmp_path / "broken.mp4"
    broken.write_bytes(b"not a video at all")
    assert main(["track", str(broken), str(broken), "--model", "hand", "--rig",
                 str(whole_hand / "rig.json"), "--init", str(whole_hand / "initial_state.json"),
                 "-o", str(tmp_path / "c"), "--quiet"]) == 2
    assert "broken.mp4" in one_line_error(capsys)


def test_interrupted_run_keeps_every_tracked_frame(whole_hand, tmp_path):
    seq = open_sequence(whole_hand)

    def frames_then_ctrl_c():
        for i, images in enumerate(seq):
            if i == 3:
                raise KeyboardInterrupt
            yield images

    tracker = FeatureTracker(seq.model, seq.rig)
    run = run_tracker(tracker, seq.model, seq.rig, frames_then_ctrl_c(), seq.initial_state,
                      tmp_path / "out", progress=False)
    assert run.interrupted and run.n_frames == 3
    assert len(read_state_log(tmp_path / "out" / "states.csv", seq.model).frames) == 3
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["interrupted"]


def test_demo_renders_tracks_and_reports(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "-o", str(out), "--frames", "8", "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "fingertip error" in text and "report:" in text
    metrics = json.loads((out / "evaluation" / "metrics.json").read_text())
    assert metrics["track_life"]["frames"] == 8
    assert (out / "evaluation" / "report.md").exists()


def test_model_show_and_errors(capsys):
    assert main(["model", "show", "hand"]) == 0
    text = capsys.readouterr().out
    assert "q9   index.pip" in text and "28 states" in text
    assert main(["model", "show", "no-such-model"]) == 2
    assert "no shipped model" in one_line_error(capsys)


def test_track_measures_the_size_of_a_smaller_hand_from_the_datasets_start(tmp_path, capsys):
    """A dataset of a hand 0.9 times the model's size: the feature tracker measures the
    size at the dataset's (true) start and logs it; ``--option start_size=false`` keeps
    the model's size and tracks the fingertips worse; from a video (footage, ``--init
    FILE``) the size is not measured."""
    folder = tmp_path / "small"
    assert main(["render", "whole-hand", "-o", str(folder), "--frames", "4",
                 "--hand-scale", "0.9"]) == 0
    seq = open_sequence(folder)
    tips = [i for i, n in enumerate(seq.truth.keypoint_names) if n.endswith(".tip")]
    from digiteyes.kinematics.keypoints import hand_keypoints

    errors = {}
    for name, extra in (("sized", []), ("fixed", ["--option", "start_size=false"])):
        out = tmp_path / name
        assert main(["track", str(folder), "-o", str(out), "--quiet", "--no-overlay",
                     *extra]) == 0
        log = read_state_log(out / "states.csv", seq.model)
        summary = json.loads((out / "summary.json").read_text())
        if name == "sized":
            assert np.allclose(log.hand_scale, log.hand_scale[0])
            assert summary["hand_scale"] == pytest.approx(0.9, abs=0.021)
            assert (out / "hand-measured.dh").exists()
        else:
            assert np.allclose(log.hand_scale, 1.0) and summary["hand_scale"] is None
        estimated = hand_keypoints(seq.model, log.states, log.hand_scale)[1]
        errors[name] = np.linalg.norm(estimated[:, tips] - seq.truth.keypoints_3d[:, tips],
                                      axis=-1).mean()
    assert errors["sized"] < 3.0 and 2.0 * errors["sized"] < errors["fixed"], errors
    videos = write_videos(seq, tmp_path)
    out = tmp_path / "video"
    assert main(["track", *videos, "--tracker", "features", "--rig",
                 str(folder / "rig.json"), "--init", str(tmp_path / "init.json"), "-o",
                 str(out), "--quiet", "--no-overlay"]) == 0
    assert json.loads((out / "summary.json").read_text())["hand_scale"] is None
