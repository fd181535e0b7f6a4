"""``digiteyes export`` and the files ``track`` adds after tracking (joint angles, the
filtered log), on a state log written from true states (no tracking needed)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from digiteyes.cli import main
from digiteyes.filters import OneEuroOptions, one_euro_filter
from digiteyes.io import StateLogWriter, read_state_log
from digiteyes.io.track_extras import model_of_log, write_track_extras
from digiteyes.kinematics.joint_angles import ANATOMICAL_NAMES, joint_angles_deg
from digiteyes.synth.scenarios import build_scenario


@pytest.fixture(scope="module")
def track_dir(tmp_path_factory):
    scenario = build_scenario("whole-hand")
    out = tmp_path_factory.mktemp("track")
    with StateLogWriter(out / "states.csv", scenario.model) as log:
        for t, q in enumerate(scenario.states[:15]):
            log.append(t, q, time_s=0.01, lost=t == 9, residual_rms_px=0.5, iterations=5)
    (out / "summary.json").write_text(json.dumps({"frames": 15, "fps": 12.5}))
    return out, scenario.model, scenario.states[:15]


def test_track_extras_write_angles_and_filtered_log(track_dir):
    out, model, states = track_dir
    files = write_track_extras(out, model, 10.0, smooth=None)
    assert set(files) == {"joint-angles"}
    files = write_track_extras(out, model, 10.0, smooth=OneEuroOptions())
    assert set(files) == {"joint-angles", "states-smoothed", "joint-angles-smoothed"}
    smoothed = read_state_log(files["states-smoothed"], model)
    reset = np.zeros(15, dtype=bool)
    reset[10] = True  # the frame after the lost one
    np.testing.assert_allclose(smoothed.states,
                               one_euro_filter(model, states, 10.0, reset=reset), atol=1e-12)
    with open(files["joint-angles"], newline="") as handle:
        rows = list(csv.reader(handle))
    names, degrees = joint_angles_deg(model, states)
    assert rows[0] == ["frame", *names]
    assert len(names) == 21 and set(names) == {v[0] for v in ANATOMICAL_NAMES.values()}
    np.testing.assert_allclose(np.array(rows[1:], dtype=float)[:, 1:], degrees, atol=1e-5)
    thumb = names.index("thumb_ip_flexion")
    assert degrees[0, thumb] == pytest.approx(-np.degrees(states[0, model.state_index(
        "thumb.ip")]))


def test_export_command_writes_every_format(track_dir, tmp_path, capsys):
    out, model, _ = track_dir
    assert model_of_log(out / "states.csv") is model
    assert main(["export", str(out), "-o", str(tmp_path), "--format", "bvh", "--format",
                 "gltf", "--format", "csv", "--smooth"]) == 0
    printed = capsys.readouterr().out
    assert "12.5 frames/s" in printed and "One Euro filtered" in printed
    assert {p.name for p in tmp_path.iterdir()} == {"track.bvh", "track.glb", "track.csv"}
    assert "Frame Time: 0.08\n" in (tmp_path / "track.bvh").read_text()


def test_export_command_errors_in_one_line(tmp_path, capsys):
    assert main(["export", str(tmp_path), "-o", str(tmp_path / "x"), "--format", "csv"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("digiteyes: error:") and "states.csv" in err


def test_a_track_of_a_hand_of_its_own_size_is_exported_at_that_size(tmp_path, capsys):
    """A log with ``hand_scale`` (the keypoint tracker's fitted size): the exported
    keypoints are those of the hand of the track's median size, and the command says so."""
    from digiteyes.kinematics.keypoints import hand_keypoints

    scenario = build_scenario("whole-hand")
    states = scenario.states[:5]
    track = tmp_path / "track"
    with StateLogWriter(track / "states.csv", scenario.model, hand_scale=True) as log:
        for t, q in enumerate(states):
            log.append(t, q, time_s=0.01, lost=False, residual_rms_px=0.5, iterations=5,
                       hand_scale=0.9)
    assert main(["export", str(track), "-o", str(tmp_path / "out"), "--format", "csv"]) == 0
    assert "the hand 0.900 times the model" in capsys.readouterr().out
    with open(tmp_path / "out" / "track.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    names, points = hand_keypoints(scenario.model, states, 0.9)
    tip = names.index("index.tip")
    got = np.array([[float(r[f"index.tip_{a}_mm"]) for a in "xyz"] for r in rows])
    np.testing.assert_allclose(got, points[:, tip], atol=1e-9)


def test_a_track_folder_carries_its_model_and_export_uses_it(tmp_path, capsys):
    """A track of a personal model (lengths other than the shipped hand's): the folder's
    ``model.dh`` (what ``track`` writes) is the model ``export`` and the replay read, not
    the shipped model whose state names the log shares."""
    from digiteyes.io.track_extras import model_of_log, write_track_model
    from digiteyes.kinematics.keypoints import hand_keypoints
    from digiteyes.kinematics.scaling import scaled_model

    scenario = build_scenario("whole-hand")
    personal = scaled_model(scenario.model, 0.85, name="my-hand")
    states = scenario.states[:4]
    track = tmp_path / "track"
    with StateLogWriter(track / "states.csv", personal) as log:
        for t, q in enumerate(states):
            log.append(t, q, time_s=0.01, lost=False, residual_rms_px=0.5, iterations=5)
    assert model_of_log(track / "states.csv").name == "hand"  # by its header alone
    write_track_model(track, personal)
    found = model_of_log(track / "states.csv")
    assert found.name == "my-hand" and found.state_names == personal.state_names
    assert main(["export", str(track), "-o", str(tmp_path / "out"), "--format", "csv"]) == 0
    with open(tmp_path / "out" / "track.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    names, points = hand_keypoints(personal, states)
    tip = names.index("middle.tip")
    got = np.array([[float(r[f"middle.tip_{a}_mm"]) for a in "xyz"] for r in rows])
    np.testing.assert_allclose(got, points[:, tip], atol=1e-6)
