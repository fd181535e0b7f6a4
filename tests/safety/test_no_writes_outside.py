"""Issue 12, items 1-4: commands delete only what they wrote and never follow names from
input files out of their folder."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from digiteyes.camera import Camera, Rig
from digiteyes.cli import main
from digiteyes.errors import DatasetError
from digiteyes.io import SequenceWriter, open_sequence
from digiteyes.io.safe_paths import MANIFEST, check_name, inside
from digiteyes.kinematics import load_model


def _victim(tmp_path: Path) -> Path:
    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "a.txt").write_text("precious\n")
    (victim / "000000.png").write_bytes(b"not mine")
    return victim


@pytest.mark.parametrize("cameras, files", [
    (["../victim"], {"x": "../victim/a.txt"}),
    ([str(Path("/").resolve() / "tmp" / "nowhere")], {"x": "/etc/hostname"}),
])
def test_render_force_never_follows_names_out_of_its_folder(tmp_path, one_line_error,
                                                             cameras, files, snapshot):
    """Item 1: the old sequence.json names files outside DIR; --force refuses them."""
    victim = _victim(tmp_path)
    before = snapshot(victim)
    trap = tmp_path / "trap"
    trap.mkdir()
    (trap / "sequence.json").write_text(json.dumps(
        {"cameras": cameras, "frames": {"kind": "png", "files": files}}))
    assert main(["render", "whole-hand", "-o", str(trap), "--force", "--frames", "1"]) == 2
    assert "not a plain name" in one_line_error()
    assert snapshot(victim) == before


def test_render_force_replaces_its_own_sequence(tmp_path):
    out = tmp_path / "seq"
    assert main(["render", "mouse", "-o", str(out), "--frames", "3"]) == 0
    (out / "notes.txt").write_text("mine")
    assert main(["render", "mouse", "-o", str(out), "--frames", "2", "--force"]) == 0
    assert open_sequence(out).n_frames == 2
    assert not (out / "cam0" / "000002.png").exists()
    assert (out / "notes.txt").read_text() == "mine", "files it did not write stay"


def test_demo_keeps_a_folder_it_did_not_write(tmp_path, one_line_error, snapshot):
    """Item 2: a bad scenario or a foreign folder leaves the folder untouched."""
    thesis = tmp_path / "my-thesis-folder"
    (thesis / "sequence").mkdir(parents=True)
    (thesis / "sequence" / "chapter1.tex").write_text("years of work")
    (thesis / "notes.txt").write_text("more work")
    before = snapshot(thesis)
    assert main(["demo", "-o", str(thesis), "--scenario", "bogus"]) == 2
    one_line_error()
    assert snapshot(thesis) == before
    assert main(["demo", "-o", str(thesis), "--frames", "2", "--quiet"]) == 2
    assert "did not write" in one_line_error()
    assert snapshot(thesis) == before


def test_demo_replaces_only_what_its_manifest_lists(tmp_path):
    out = tmp_path / "demo"
    assert main(["demo", "-o", str(out), "--frames", "2", "--quiet",
                 "--scenario", "mouse"]) == 0
    listed = json.loads((out / MANIFEST).read_text())["files"]
    assert "track/states.csv" in listed and "sequence/sequence.json" in listed
    (out / "mine.txt").write_text("keep me")
    assert main(["demo", "-o", str(out), "--frames", "3", "--quiet",
                 "--scenario", "mouse"]) == 0
    assert (out / "mine.txt").read_text() == "keep me"
    assert open_sequence(out / "sequence").n_frames == 3


def test_sequence_writer_refuses_camera_names_with_paths(tmp_path, snapshot):
    """Item 3: a camera named ../../escape cannot write outside the folder."""
    model = load_model("hand")
    cam = Camera.look_at("../../escape", (0, -400, 300), (0, 50, 0), width=32, height=24,
                         focal_px=40)
    folder = tmp_path / "a" / "b" / "seq"
    with pytest.raises(DatasetError, match="not a plain name"):
        SequenceWriter(folder, model, Rig((cam,)), np.zeros(model.n_q) + _neutral(model), 10.0)
    assert snapshot(tmp_path) == {}


def _neutral(model) -> np.ndarray:
    from digiteyes.kinematics import State

    return State(model).q


def test_sequence_reader_never_reads_outside_its_folder(tmp_path):
    """Item 4: sequence.json naming a system file as its model is refused without echoing
    the file."""
    out = tmp_path / "seq"
    assert main(["render", "mouse", "-o", str(out), "--frames", "1"]) == 0
    secret = tmp_path / "secret.txt"
    secret.write_text("root:x:0:0:TOP-SECRET\n")
    payload = json.loads((out / "sequence.json").read_text())
    for key, value in (("model", "../secret.txt"), ("model", str(secret)),
                       ("rig", "../secret.txt"), ("initial_state", "../secret.txt")):
        (out / "sequence.json").write_text(json.dumps({**payload, key: value}))
        with pytest.raises(DatasetError) as info:
            open_sequence(out)
        assert "TOP-SECRET" not in str(info.value) and "side" in str(info.value)
    link = out / "link.dh"
    link.symlink_to(secret)
    (out / "sequence.json").write_text(json.dumps({**payload, "model": "link.dh"}))
    with pytest.raises(DatasetError, match="outside"):
        open_sequence(out)


@pytest.mark.parametrize("name", ["", ".", "..", "a/b", "a\\b", "/abs", "c:x", "x\0y",
                                  "n" * 300, 7, None, " padded"])
def test_check_name_refuses_anything_but_a_plain_name(name):
    with pytest.raises(DatasetError):
        check_name(name, "camera", "here")


def test_inside_accepts_children_and_refuses_escapes(tmp_path):
    assert inside(tmp_path, "cam0/000001.png", "frame", "here") == tmp_path / "cam0/000001.png"
    for bad in ("../x", "a/../../x", str(tmp_path.parent / "x"), "", 3):
        with pytest.raises(DatasetError):
            inside(tmp_path, bad, "frame", "here")
