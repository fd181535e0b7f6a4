"""Sequence folders: round trips, crash safety, resume, and errors that name the file."""

from __future__ import annotations

import json
import shutil

import cv2
import numpy as np
import pytest

from digiteyes.camera import Camera, Rig, save_rig
from digiteyes.errors import DatasetError
from digiteyes.io import FrameTruth, SequenceWriter, open_sequence
from digiteyes.kinematics import State, write_states_csv


def write_sequence(folder, hand, rig, images_of, truth_of, n, **kwargs):
    with SequenceWriter(folder, hand, rig, hand.neutral(), 25.0, **kwargs) as writer:
        for i in range(n):
            writer.write_frame(images_of(i), truth_of(i))
    return writer


def assert_truth_equal(truth, truth_of, n):
    assert len(truth) == n
    for i in range(n):
        expected = truth_of(i)
        np.testing.assert_array_equal(truth.states[i], expected.state)
        assert truth.keypoint_names == expected.keypoint_names
        np.testing.assert_array_equal(truth.keypoints_3d[i], expected.keypoints_3d)
        np.testing.assert_array_equal(truth.keypoints_2d[i], expected.keypoints_2d)
        np.testing.assert_array_equal(truth.visible[i], expected.visible)


def test_png_round_trip_grey_and_rgb(tmp_path, hand, rig, images_of, truth_of):
    folder = tmp_path / "seq"
    write_sequence(folder, hand, rig, images_of, truth_of, 3, name="demo",
                   scenario={"motion": "wave", "seed": 3})
    seq = open_sequence(folder)
    assert (seq.name, seq.fps, seq.n_frames, len(seq), seq.complete) == ("demo", 25.0, 3, 3, True)
    assert seq.camera_names == ["cam0", "cam1"] == seq.rig.names
    assert seq.model.state_names == hand.state_names
    assert seq.scenario == {"motion": "wave", "seed": 3}
    np.testing.assert_array_equal(seq.initial_state, hand.neutral())
    for cam_read, cam in zip(seq.rig.cameras, rig.cameras, strict=True):
        np.testing.assert_allclose(cam_read.K, cam.K)
        np.testing.assert_allclose(cam_read.T_cam_world, cam.T_cam_world)
    frames = list(seq)
    assert len(frames) == 3
    for i, images in enumerate(frames):
        expected = images_of(i)
        assert images[0].shape == (48, 64) and images[1].shape == (48, 64, 3)
        for got, want in zip(images, expected, strict=True):
            np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(seq.frame(1)[1], images_of(1)[1])
    assert_truth_equal(seq.truth, truth_of, 3)
    payload = json.loads((folder / "sequence.json").read_text())
    assert payload["frames"] == {"kind": "png", "pattern": "{camera}/{index:06d}.png"}
    assert (folder / "cam1" / "000002.png").is_file()
    assert not list(folder.rglob("*.tmp"))


def test_png_keeps_16_bit_images(tmp_path, hand, rig):
    rng = np.random.default_rng(5)
    images = [rng.integers(0, 65536, (48, 64), dtype=np.uint16),
              rng.integers(0, 65536, (48, 64, 3), dtype=np.uint16)]
    with SequenceWriter(tmp_path / "s", hand, rig, hand.neutral(), 30) as writer:
        writer.write_frame(images)
    seq = open_sequence(tmp_path / "s")
    assert seq.truth is None
    for got, want in zip(seq.frame(0), images, strict=True):
        assert got.dtype == np.uint16
        np.testing.assert_array_equal(got, want)


def test_lossless_video_round_trip(tmp_path, hand, rig, images_of, truth_of):
    rgb = [np.stack([images_of(i)[0]] * 3, axis=-1) for i in range(4)]
    with SequenceWriter(tmp_path / "v", hand, rig, hand.neutral(), 30, video=True) as writer:
        for i in range(4):
            writer.write_frame([rgb[i], images_of(i)[1]], truth_of(i))
    assert sorted(p.name for p in (tmp_path / "v").glob("*.mkv")) == ["cam0.mkv", "cam1.mkv"]
    seq = open_sequence(tmp_path / "v")
    assert seq.n_frames == 4 and seq.frames_spec["lossless"] is True
    for i, images in enumerate(seq):
        np.testing.assert_array_equal(images[0], rgb[i])
        np.testing.assert_array_equal(images[1], images_of(i)[1])
    np.testing.assert_array_equal(seq.frame(2)[1], images_of(2)[1])  # seek backwards
    np.testing.assert_array_equal(seq.frame(0)[0], rgb[0])
    seq.close()
    assert_truth_equal(seq.truth, truth_of, 4)


def test_h264_video_round_trip_within_tolerance(tmp_path, hand, rig):
    yy, xx = np.mgrid[0:48, 0:64]
    grey = [((xx * 3 + yy * 2 + 10 * i) % 256).astype(np.uint8) for i in range(5)]
    with SequenceWriter(tmp_path / "h", hand, rig, hand.neutral(), 30, video="h264") as writer:
        for im in grey:
            writer.write_frame([im, im])
    seq = open_sequence(tmp_path / "h")
    assert seq.frames_spec["color"] == "gray" and seq.frames_spec["lossless"] is False
    for i, images in enumerate(seq):
        assert images[0].shape == (48, 64)
        assert np.abs(images[0].astype(int) - grey[i]).mean() < 3.0


def test_exception_inside_with_leaves_consistent_dataset(tmp_path, hand, rig, images_of,
                                                        truth_of):
    folder = tmp_path / "crash"
    with pytest.raises(RuntimeError, match="render failed"):
        with SequenceWriter(folder, hand, rig, hand.neutral(), 30,
                            checkpoint_every=4) as writer:
            for i in range(6):
                writer.write_frame(images_of(i), truth_of(i))
            raise RuntimeError("render failed")
    seq = open_sequence(folder)
    assert (seq.n_frames, seq.complete) == (6, False)
    assert_truth_equal(seq.truth, truth_of, 6)


def test_unclosed_writer_counts_only_checkpointed_frames(tmp_path, hand, rig, images_of,
                                                         truth_of):
    folder = tmp_path / "killed"
    writer = SequenceWriter(folder, hand, rig, hand.neutral(), 30, checkpoint_every=4)
    for i in range(7):
        writer.write_frame(images_of(i), truth_of(i))
    # the process dies here: no close(); frames 4..6 are on disk but not yet counted
    seq = open_sequence(folder)
    assert (seq.n_frames, seq.complete) == (4, False)
    assert_truth_equal(seq.truth, truth_of, 4)
    np.testing.assert_array_equal(seq.frame(3)[0], images_of(3)[0])
    with pytest.raises(IndexError):
        seq.frame(4)


def test_resume_continues_after_last_complete_frame(tmp_path, hand, rig, images_of, truth_of):
    folder = tmp_path / "resume"
    writer = SequenceWriter(folder, hand, rig, hand.neutral(), 30, checkpoint_every=4)
    for i in range(6):
        writer.write_frame(images_of(i), truth_of(i))
    with pytest.raises(DatasetError, match=r"incomplete.*resume"):
        SequenceWriter(folder, hand, rig, hand.neutral(), 30)
    with SequenceWriter(folder, hand, rig, hand.neutral(), 30, resume=True) as resumed:
        assert resumed.n_written == 4
        for i in range(resumed.n_written, 9):
            resumed.write_frame(images_of(i), truth_of(i))
    seq = open_sequence(folder)
    assert (seq.n_frames, seq.complete) == (9, True)
    assert_truth_equal(seq.truth, truth_of, 9)
    for i, images in enumerate(seq):
        np.testing.assert_array_equal(images[1], images_of(i)[1])
    with pytest.raises(DatasetError, match="already complete"):
        SequenceWriter(folder, hand, rig, hand.neutral(), 30, resume=True)


def test_resume_refuses_another_rig(tmp_path, hand, rig, images_of):
    folder = tmp_path / "r"
    writer = SequenceWriter(folder, hand, rig, hand.neutral(), 30, checkpoint_every=1)
    writer.write_frame(images_of(0))
    other = Rig((rig[0], Camera.look_at("cam1", (0, 400, 300), (0, 0, 0), width=64,
                                          height=48, focal_px=80)))
    with pytest.raises(DatasetError, match=r"rig.json: differs"):
        SequenceWriter(folder, hand, other, hand.neutral(), 30, resume=True)


def test_resume_of_empty_folder_starts_afresh(tmp_path, hand, rig, images_of):
    with SequenceWriter(tmp_path / "new", hand, rig, hand.neutral(), 30, resume=True) as w:
        assert w.n_written == 0
        w.write_frame(images_of(0))
    assert open_sequence(tmp_path / "new").n_frames == 1


def test_overwrite_replaces_old_frames(tmp_path, hand, rig, images_of, truth_of):
    folder = tmp_path / "seq"
    write_sequence(folder, hand, rig, images_of, truth_of, 5)
    with pytest.raises(DatasetError, match=r"complete sequence.*overwrite"):
        SequenceWriter(folder, hand, rig, hand.neutral(), 30)
    with SequenceWriter(folder, hand, rig, hand.neutral(), 30, overwrite=True) as writer:
        for i in range(2):
            writer.write_frame(images_of(10 + i))
    seq = open_sequence(folder)
    assert seq.n_frames == 2 and seq.truth is None
    assert not (folder / "cam0" / "000004.png").exists()
    assert not (folder / "truth" / "states.csv").exists()
    np.testing.assert_array_equal(seq.frame(1)[0], images_of(11)[0])


def test_refuses_non_empty_foreign_folder(tmp_path, hand, rig):
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(DatasetError, match="not empty"):
        SequenceWriter(tmp_path, hand, rig, hand.neutral(), 30)


def test_unwritable_folder_names_the_path(tmp_path, hand, rig):
    blocker = tmp_path / "file.txt"
    blocker.write_text("not a folder")
    with pytest.raises(DatasetError, match=r"file.txt"):
        SequenceWriter(blocker / "seq", hand, rig, hand.neutral(), 30)


def test_write_frame_checks_images_and_truth(tmp_path, hand, rig, images_of, truth_of):
    writer = SequenceWriter(tmp_path / "s", hand, rig, hand.neutral(), 30)
    with pytest.raises(DatasetError, match="2 camera"):
        writer.write_frame(images_of(0)[:1])
    with pytest.raises(DatasetError, match=r"cam1.*expects 64x48.*got 32x48"):
        writer.write_frame([images_of(0)[0], images_of(0)[1][:, :32]])
    with pytest.raises(DatasetError, match="uint8"):
        writer.write_frame([images_of(0)[0].astype(float), images_of(0)[1]])
    bad = truth_of(0)
    bad = FrameTruth(bad.state, bad.keypoint_names, bad.keypoints_3d,
                     bad.keypoints_2d[:1], bad.visible)
    with pytest.raises(DatasetError, match="keypoints_2d must have shape"):
        writer.write_frame(images_of(0), bad)
    writer.write_frame(images_of(0), truth_of(0))
    with pytest.raises(DatasetError, match="every frame or for none"):
        writer.write_frame(images_of(1))
    writer.close()
    assert open_sequence(tmp_path / "s").n_frames == 1


def test_missing_png_is_named(tmp_path, hand, rig, images_of, truth_of):
    folder = tmp_path / "seq"
    write_sequence(folder, hand, rig, images_of, truth_of, 3)
    (folder / "cam1" / "000001.png").unlink()
    with pytest.raises(DatasetError, match=r"cam1/000001.png: missing frame 1.*n_frames=3"):
        open_sequence(folder)


def test_image_size_other_than_rig_is_named(tmp_path, hand, rig, images_of, truth_of):
    folder = tmp_path / "seq"
    write_sequence(folder, hand, rig, images_of, truth_of, 3)
    cv2.imwrite(str(folder / "cam0" / "000002.png"), np.zeros((10, 20), np.uint8))
    seq = open_sequence(folder)
    with pytest.raises(DatasetError, match=r"000002.png: frame 2 is 20x10.*expects 64x48"):
        seq.frame(2)
    cv2.imwrite(str(folder / "cam0" / "000000.png"), np.zeros((10, 20), np.uint8))
    with pytest.raises(DatasetError, match=r"000000.png"):
        open_sequence(folder)


def test_truth_length_must_match_n_frames(tmp_path, hand, rig, images_of, truth_of):
    folder = tmp_path / "seq"
    write_sequence(folder, hand, rig, images_of, truth_of, 3)
    payload = json.loads((folder / "sequence.json").read_text())
    payload["n_frames"] = 2
    (folder / "sequence.json").write_text(json.dumps(payload))
    with pytest.raises(DatasetError, match=r"states.csv: holds truth for 3 frames, expected 2"):
        open_sequence(folder)


def test_cameras_must_match_rig_and_format_is_checked(tmp_path, hand, rig, images_of,
                                                       truth_of):
    folder = tmp_path / "seq"
    write_sequence(folder, hand, rig, images_of, truth_of, 1)
    payload = json.loads((folder / "sequence.json").read_text())
    (folder / "sequence.json").write_text(json.dumps(payload | {"cameras": ["cam1", "cam0"]}))
    with pytest.raises(DatasetError, match="do not match the rig"):
        open_sequence(folder)
    (folder / "sequence.json").write_text(json.dumps(payload | {"version": 7}))
    with pytest.raises(DatasetError, match="unsupported version 7"):
        open_sequence(folder)
    (folder / "sequence.json").unlink()
    with pytest.raises(DatasetError, match=r"sequence.json: no such file"):
        open_sequence(folder)


def test_hand_made_sequence_with_own_pattern_and_states_only(tmp_path, hand, rig):
    """The "bring your own recording" path of docs/dataset.md, written without digiteyes'
    writer: own file names starting at 1, truth states only."""
    folder = tmp_path / "mine"
    for cam in rig.names:
        (folder / "frames" / cam).mkdir(parents=True)
        for i in (1, 2):
            cv2.imwrite(str(folder / "frames" / cam / f"img_{i:03d}.png"),
                        np.full((48, 64), 10 * i, np.uint8))
    shutil.copy(hand.path, folder / "hand.dh")
    save_rig(rig, folder / "cams.json")
    State(hand).save_json(folder / "start.json")
    states = np.tile(hand.neutral(), (2, 1))
    states[1, 8] = 0.5
    (folder / "gt").mkdir()
    write_states_csv(hand, folder / "gt" / "q.csv", states)
    (folder / "sequence.json").write_text(json.dumps({
        "format": "digiteyes-sequence", "version": 1, "model": "hand.dh", "rig": "cams.json",
        "initial_state": "start.json", "fps": 30, "n_frames": 2, "cameras": rig.names,
        "frames": {"kind": "png", "pattern": "frames/{camera}/img_{index:03d}.png",
                   "first_index": 1},
        "truth": {"states": "gt/q.csv", "keypoints": None}}))
    seq = open_sequence(folder)
    assert seq.name == "mine" and seq.complete
    assert seq.frame(1)[1][0, 0] == 20
    np.testing.assert_array_equal(seq.truth.states, states)
    assert seq.truth.keypoint_names == () and seq.truth.keypoints_3d.shape == (2, 0, 3)


def test_full_disk_names_the_file(tmp_path, hand, rig, images_of, monkeypatch):
    import digiteyes.io.dataset as dataset

    writer = SequenceWriter(tmp_path / "s", hand, rig, hand.neutral(), 30)

    def full(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(dataset.os, "replace", full)
    with pytest.raises(DatasetError, match=r"cam0/000000\.png: cannot write \(No space left"):
        writer.write_frame(images_of(0))
    monkeypatch.undo()
    assert open_sequence(tmp_path / "s").n_frames == 0


def test_video_of_another_size_than_rig_is_named(tmp_path, hand, rig, images_of):
    folder = tmp_path / "v"
    with SequenceWriter(folder, hand, rig, hand.neutral(), 30, video=True) as writer:
        writer.write_frame([images_of(0)[1], images_of(0)[1]])
    wide = Rig(tuple(Camera.create(c.name, c.K, 80, 48, c.T_cam_world) for c in rig.cameras))
    save_rig(wide, folder / "rig.json")
    with pytest.raises(DatasetError, match=r"cam0\.mkv: frame 0 is 64x48.*expects 80x48"):
        open_sequence(folder)
