"""``pose``, ``calibrate-camera`` and ``calibrate-hand`` end to end on rendered images."""

from __future__ import annotations

import csv
import json

import cv2
import numpy as np
import pytest

from digiteyes import load_model
from digiteyes.camera import Camera, Rig, load_rig, save_rig
from digiteyes.camera.calibration import CharucoBoard, render_charuco, render_chessboard
from digiteyes.camera.mirror import mirrored_rig
from digiteyes.cli import main
from digiteyes.detect.hand_size import model_hand_length
from digiteyes.detect.mediapipe_detector import mediapipe_available
from digiteyes.kinematics.rotations import matrix_from_quaternion, quaternion_from_rotvec
from digiteyes.synth.options import RenderOptions
from digiteyes.synth.scenarios import basis_joint_angles, build_scenario
from digiteyes.synth.views import render_views


@pytest.fixture(scope="module")
def hand_image(tmp_path_factory):
    """A rendered open right hand on a grey wall, its camera's rig file and the truth."""
    hand = load_model("hand")
    cam = Camera.look_at("front", eye=(0, 0, 450), target=(0, 0, 0), up=(0, -1, 0))
    q = basis_joint_angles(hand, "EEEEE")
    q[0:4] = quaternion_from_rotvec(np.array([0.2, 0.1, 3.0]))
    q[4:7] = (0.0, 30.0, 0.0)
    view = render_views(hand, np.clip(q, hand.lower, hand.upper), [cam],
                        RenderOptions(color=True, background="uniform", background_level=0.45),
                        rng=0)[0]
    folder = tmp_path_factory.mktemp("pose")
    path = folder / "hand.png"
    cv2.imwrite(str(path), cv2.cvtColor(view.image, cv2.COLOR_RGB2BGR))
    save_rig(Rig((cam,)), folder / "rig.json")
    return path, folder / "rig.json", cam.to_camera(view.keypoints_3d)


def test_pose_writes_json_and_csv(hand_image, tmp_path):
    image, rig, truth_cam = hand_image
    out = tmp_path / "out"
    assert main(["pose", str(image), "--rig", str(rig), "--detector", "classic",
                 "-o", str(out)]) == 0
    record = json.loads((out / "hand.json").read_text())
    hand = record["hand"]
    assert hand["scale"] == 1.0 and not hand["scale_fitted"]
    wrist = np.array(hand["keypoints_camera_mm"]["front"]["wrist"])
    assert wrist[2] == pytest.approx(truth_cam[:, 2].mean(), rel=0.12)  # 450 mm away
    assert set(hand["joint_angles_deg"]) >= {"index.mcp", "thumb.ip"}
    with open(out / "hand.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 21 and rows[0]["keypoint"] == "wrist"
    assert float(rows[0]["z_cam_mm"]) == pytest.approx(wrist[2], abs=0.01)


def test_pose_of_a_left_hand_is_the_mirror_image_of_the_right_hands(hand_image, tmp_path):
    """The rendered right hand flipped is a left hand (with the mirrored rig). ``--hand
    left`` fits it as the right hand of its mirror image, which is the original: the
    reported detections and points are exactly the right hand's, reflected."""
    image, rig_path, _ = hand_image
    flipped = tmp_path / "left.png"
    cv2.imwrite(str(flipped), cv2.imread(str(image))[:, ::-1])
    save_rig(mirrored_rig(load_rig(rig_path)), tmp_path / "left-rig.json")
    assert main(["pose", str(image), "--rig", str(rig_path), "--detector", "classic",
                 "-o", str(tmp_path / "r")]) == 0
    assert main(["pose", str(flipped), "--rig", str(tmp_path / "left-rig.json"), "--hand",
                 "left", "--detector", "classic", "-o", str(tmp_path / "l")]) == 0
    right = json.loads((tmp_path / "r" / "hand.json").read_text())
    left = json.loads((tmp_path / "l" / "left.json").read_text())
    assert left["hand_side"] == "left" and right["hand_side"] == "right"
    width = load_rig(rig_path)[0].width
    for name, (u, v) in right["detections"]["front"]["keypoints_px"].items():
        assert left["detections"]["front"]["keypoints_px"][name] == \
            pytest.approx([width - 1 - u, v], abs=1e-6)
    for name, (x, y, z) in right["hand"]["keypoints_camera_mm"]["front"].items():
        assert left["hand"]["keypoints_camera_mm"]["front"][name] == \
            pytest.approx([-x, y, z], abs=1e-2)
    assert left["hand"]["joint_angles_deg"] == pytest.approx(right["hand"]["joint_angles_deg"])
    with open(tmp_path / "l" / "left.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    wrist = left["hand"]["keypoints_camera_mm"]["front"]["wrist"]
    assert float(rows[0]["x_cam_mm"]) == pytest.approx(wrist[0], abs=0.01)


def test_pose_keeps_the_results_of_images_of_the_same_name(hand_image, tmp_path):
    """``a/hand.png`` and ``b/hand.png`` (the second the first turned upside down): two
    results, each of its own image, neither overwritten."""
    image, rig, _ = hand_image
    first, second = tmp_path / "a" / "hand.png", tmp_path / "b" / "hand.png"
    for path, picture in ((first, cv2.imread(str(image))),
                          (second, cv2.rotate(cv2.imread(str(image)), cv2.ROTATE_180))):
        path.parent.mkdir()
        cv2.imwrite(str(path), picture)
    out = tmp_path / "out"
    assert main(["pose", str(first), str(second), "--rig", str(rig), "--detector", "classic",
                 "-o", str(out)]) == 0
    records = [json.loads((out / name).read_text()) for name in ("hand.json", "hand-2.json")]
    assert [r["images"] for r in records] == [[str(first)], [str(second)]]
    # turning the image by a half turn about its centre (the principal point) turns the
    # hand about the optical axis: (x, y, z) -> (-x, -y, z) in the camera frame
    wrists = [np.array(r["hand"]["keypoints_camera_mm"]["front"]["wrist"]) for r in records]
    np.testing.assert_allclose(wrists[1], wrists[0] * [-1, -1, 1], atol=10.0)
    assert sorted(p.name for p in out.iterdir()) == ["hand-2.csv", "hand-2.json", "hand.csv",
                                                     "hand.json"]


def test_pose_without_a_rig_uses_the_default_camera(hand_image, tmp_path):
    image, _, _ = hand_image
    assert main(["pose", str(image), "--detector", "classic", "-o", str(tmp_path)]) == 0
    record = json.loads((tmp_path / "hand.json").read_text())
    assert record["hand"] is not None and "camera" in record["hand"]["keypoints_camera_mm"]


@pytest.mark.skipif(not mediapipe_available(), reason="optional extra digiteyes[mediapipe]")
def test_pose_auto_asks_the_classic_detector_where_mediapipe_sees_no_hand(tmp_path):
    """The flesh hand's palm-on, back-lit webcam render: MediaPipe finds no hand in it;
    ``pose`` (``--detector auto``) then reports the classic detector's hand."""
    scenario = build_scenario("webcam-1cam", seed=0, n_frames=1)
    view = render_views(scenario.model, scenario.states[0], list(scenario.rig.cameras),
                        RenderOptions(appearance="flesh", color=True, background="black",
                                      background_level=0.08), rng=0)[0]
    path = tmp_path / "webcam.png"
    cv2.imwrite(str(path), cv2.cvtColor(view.image, cv2.COLOR_RGB2BGR))
    save_rig(scenario.rig, tmp_path / "rig.json")
    assert main(["pose", str(path), "--rig", str(tmp_path / "rig.json"), "-o",
                 str(tmp_path / "out")]) == 0
    record = json.loads((tmp_path / "out" / "webcam.json").read_text())
    assert record["detections"][scenario.rig.cameras[0].name]["detector"] == "classic"
    assert record["hand"] is not None


def test_pose_reports_an_unreadable_image(tmp_path, capsys):
    bad = tmp_path / "bad.png"
    bad.write_text("not an image")
    assert main(["pose", str(bad), "--detector", "classic", "-o", str(tmp_path / "o")]) == 2
    assert "not an image" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()  # nothing written, not even the folder


TRUTH_K = np.array([[650.0, 0, 318.0], [0, 650.0, 242.0], [0, 0, 1]])


def write_board_views(folder, render, centre_mm, seed):
    """Six views of a board 420 mm from a camera of :data:`TRUTH_K`, tilted up to 26 deg:
    ``render(camera, T_cam_board)`` draws one; returns the folder."""
    cam = Camera.create("truth", TRUTH_K, 640, 480)
    rng = np.random.default_rng(seed)
    folder.mkdir()
    for i in range(6):
        T = np.eye(4)
        T[:3, :3] = matrix_from_quaternion(quaternion_from_rotvec(rng.uniform(-0.45, 0.45, 3)))
        T[:3, 3] = np.array([rng.uniform(-30, 30), rng.uniform(-20, 20), 420.0]) \
            - T[:3, :3] @ np.array([*centre_mm, 0.0])
        cv2.imwrite(str(folder / f"b{i}.png"), render(cam, T))
    return folder


def test_calibrate_camera_from_a_folder(tmp_path):
    folder = write_board_views(tmp_path / "boards",
                               lambda cam, T: render_chessboard(cam, T, (7, 5), 25.0),
                               (75.0, 50.0), seed=0)
    out = tmp_path / "rig.json"
    assert main(["calibrate-camera", str(folder), "--pattern", "7x5", "--square-mm", "25",
                 "-o", str(out)]) == 0
    got = load_rig(out)[0].K
    np.testing.assert_allclose(got[[0, 1], [0, 1]], [650.0, 650.0], rtol=0.015)


def test_calibrate_camera_from_charuco_views(tmp_path, capsys):
    board = CharucoBoard((8, 6), 25.0, 18.0, "DICT_5X5_100")
    folder = write_board_views(tmp_path / "charuco",
                               lambda cam, T: render_charuco(cam, T, board),
                               (100.0, 75.0), seed=1)
    out = tmp_path / "rig.json"
    assert main(["calibrate-camera", str(folder), "--charuco", "8x6", "--square-mm", "25",
                 "--marker-mm", "18", "--dictionary", "DICT_5X5_100", "-o", str(out)]) == 0
    np.testing.assert_allclose(load_rig(out)[0].K[[0, 1], [0, 1]], [650.0, 650.0], rtol=0.015)
    assert main(["calibrate-camera", str(folder), "--charuco", "8x6", "--square-mm", "25",
                 "-o", str(out)]) == 2
    assert "--marker-mm" in capsys.readouterr().err
    # the wrong dictionary finds no board: a clear error, not a traceback
    assert main(["calibrate-camera", str(folder), "--charuco", "8x6", "--square-mm", "25",
                 "--marker-mm", "18", "-o", str(out)]) == 2
    assert "ChArUco board was found in 0 of 6" in capsys.readouterr().err


def test_calibrate_hand_from_a_measured_length(tmp_path):
    hand = load_model("hand")
    out = tmp_path / "me.dh"
    length = 1.1 * model_hand_length(hand)
    assert main(["calibrate-hand", "--hand-length-mm", f"{length:.4f}", "-o", str(out)]) == 0
    mine = load_model(out)
    assert model_hand_length(mine) == pytest.approx(length, rel=1e-4)
    assert mine.name == "me"


def test_calibrate_hand_needs_a_scale_source(tmp_path, capsys):
    assert main(["calibrate-hand", "-o", str(tmp_path / "x.dh")]) == 2
    assert "one camera cannot see the hand's size" in capsys.readouterr().err


def test_calibrate_hand_with_the_classic_detector_keeps_one_scale(tmp_path, capsys):
    """Two rendered views of an open hand: the classic detector's keypoints are placed by a
    model, so the segments are not measured and the model keeps its proportions."""
    from digiteyes.detect.link_lengths import model_lengths

    hand = load_model("hand")
    rig = Rig((Camera.look_at("left", eye=(-80, 0, 450), target=(0, 30, 0), up=(0, -1, 0)),
               Camera.look_at("right", eye=(80, 0, 450), target=(0, 30, 0), up=(0, -1, 0))))
    q = basis_joint_angles(hand, "EEEEE")
    q[0:4] = quaternion_from_rotvec(np.array([0.2, 0.1, 3.0]))
    q[4:7] = (0.0, 30.0, 0.0)
    views = render_views(hand, np.clip(q, hand.lower, hand.upper), list(rig),
                         RenderOptions(color=True, background="uniform", background_level=0.45),
                         rng=0)
    paths = []
    for cam, view in zip(rig, views, strict=True):
        paths.append(str(tmp_path / f"{cam.name}.png"))
        cv2.imwrite(paths[-1], cv2.cvtColor(view.image, cv2.COLOR_RGB2BGR))
    save_rig(rig, tmp_path / "rig.json")
    out = tmp_path / "me.dh"
    assert main(["calibrate-hand", *paths, "--rig", str(tmp_path / "rig.json"),
                 "--detector", "classic", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "cannot measure finger segments" in printed
    scale = float(printed.split("hand scale ")[1].split()[0])
    assert scale == pytest.approx(1.0, abs=0.15)  # the classic detector: 0.88 here
    np.testing.assert_allclose(model_lengths(load_model(out)), scale * model_lengths(hand),
                               rtol=2e-3)


@pytest.mark.skipif(not mediapipe_available(), reason="optional extra digiteyes[mediapipe]")
def test_pose_hand_auto_takes_the_side_mediapipe_reports(tmp_path):
    """The flesh hand's render and its mirror image: with the default --hand auto, the
    first is fitted as a right hand and the second as a left one, the same hand mirrored."""
    scenario = build_scenario("desk-2cam", seed=0, n_frames=1)
    camera = scenario.rig[0]
    view = render_views(scenario.model, scenario.states[0], [camera],
                        RenderOptions(appearance="flesh", color=True), rng=0)[0]
    for name, image in (("right.png", view.image), ("left.png", view.image[:, ::-1])):
        cv2.imwrite(str(tmp_path / name), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    save_rig(Rig((camera,)), tmp_path / "rig.json")
    save_rig(mirrored_rig(Rig((camera,))), tmp_path / "mirrored.json")
    assert main(["pose", str(tmp_path / "right.png"), "--rig", str(tmp_path / "rig.json"),
                 "-o", str(tmp_path / "r")]) == 0
    assert main(["pose", str(tmp_path / "left.png"), "--rig", str(tmp_path / "mirrored.json"),
                 "-o", str(tmp_path / "l")]) == 0
    right = json.loads((tmp_path / "r" / "right.json").read_text())
    left = json.loads((tmp_path / "l" / "left.json").read_text())
    assert (right["hand_side"], left["hand_side"]) == ("right", "left")
    r = np.array(list(right["hand"]["keypoints_camera_mm"][camera.name].values()))
    l_ = np.array(list(left["hand"]["keypoints_camera_mm"][camera.name].values()))
    assert np.linalg.norm(r - l_ * [-1.0, 1.0, 1.0], axis=1).mean() < 10.0
