"""Issue 12, items 5-12: crashes, tracebacks and silent damage, one regression test each."""

from __future__ import annotations

import io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import digiteyes.synth.sequence
from digiteyes import forward_kinematics, load_model
from digiteyes._signals import sigterm_as_interrupt
from digiteyes.camera import Camera, load_rig
from digiteyes.cli import main
from digiteyes.errors import (
    CameraError,
    DatasetError,
    DigitEyesError,
    ModelFileError,
    StateError,
)
from digiteyes.io import StateLogWriter, VideoReader, VideoWriter, open_sequence, read_state_log
from digiteyes.io.safe_paths import atomic_path
from digiteyes.io.video_lengths import check_lengths, record_missing
from digiteyes.kinematics import State, read_states_csv

K_YAML = "  rows: 3\n  cols: 3\n  dt: d\n  data: [500, 0, 20, 0, 500, 15, 0, 0, 1]\n"


def chain_model(n: int) -> str:
    """A model file of ``n`` revolute rows in one chain."""
    states = "\n".join(f"q{i} j{i} angle" for i in range(n))
    rows = "\n".join(f"{i} link{i} q{i} 0 1 0 cyl(1) {i + 1 if i + 1 < n else '-'}"
                     for i in range(n))
    return f"model chain\n[states]\n{states}\n[frames]\n{rows}\n"


# ----------------------------------------------------------------- 5: OpenCV YAML
@pytest.mark.parametrize("matrix, extra, match", [
    ("  rows: 3\n  dt: d\n  data: [500, 0, 20, 0, 500, 15, 0, 0, 1]\n", "", "lacks cols"),
    ("  rows: 3\n  cols: 40000\n  dt: d\n  data: [1, 2]\n", "", "cols must be"),
    ("  rows: 3\n  cols: 3\n  dt: d\n  data: [1, 2]\n", "", "data must list"),
    ("  rows: 3\n  cols: 3\n  dt: d\n  data: [1, 2, a, 4, 5, 6, 7, 8, 9]\n", "",
     "must be a number"),
    (K_YAML, "image_width: abc\n", "image_width"),
    (K_YAML, "image_width: -5\n", "image_width"),
    (K_YAML, "image_width: 1e308\n", "image_width"),
])
def test_opencv_yaml_is_checked_before_opencv_reads_it(tmp_path, matrix, extra, match):
    lines = [f"camera_matrix: !!opencv-matrix\n{matrix}", extra or "image_width: 40\n",
             "image_height: 30\n"]
    path = tmp_path / "calib.yml"
    path.write_text("%YAML:1.0\n---\n" + "".join(lines))
    with pytest.raises(CameraError, match=match):
        load_rig(path)


def test_good_opencv_yaml_still_loads(tmp_path):
    path = tmp_path / "calib.yml"
    path.write_text("%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n" + K_YAML
                    + "image_width: 40\nimage_height: 30\n")
    cam = load_rig(path)[0]
    assert (cam.width, cam.height) == (40, 30) and cam.K[0, 2] == 20


# ----------------------------------------------------------------- 6: model show
def test_model_show_of_a_deep_chain_is_linear(tmp_path, capsys):
    path = tmp_path / "chain.dh"
    path.write_text(chain_model(1500))
    assert main(["model", "show", str(path)]) == 0
    out = capsys.readouterr().out
    longest = max(len(line) for line in out.splitlines())
    assert longest < 120, "indentation stops growing"
    assert "[depth 1499]" in out


@pytest.mark.parametrize("rows, match", [(3_000, "more than 2000 frame rows"),
                                         (120_000, "longer than 1000000 characters")])
def test_model_with_too_many_rows_is_refused_in_one_line(tmp_path, capsys, rows, match):
    path = tmp_path / "chain.dh"
    path.write_text(chain_model(rows))
    assert main(["model", "show", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and match in err[0], err


# ----------------------------------------------------------------- 7: tracebacks
@pytest.mark.parametrize("text", ['{"q": 1' + "0" * 400 + "}", '{"q": ' + "9" * 5000 + "}",
                                  "[" * 100_000 + "]" * 100_000, '{"state": 1e999999}'])
def test_json_readers_raise_their_own_errors(tmp_path, text):
    model = load_model("hand")
    path = tmp_path / "f.json"
    path.write_text(text)
    with pytest.raises(StateError):
        State.load_json(model, path)
    with pytest.raises(CameraError):
        load_rig(path)
    seq = tmp_path / "seq"
    seq.mkdir(exist_ok=True)
    (seq / "sequence.json").write_text(text)
    with pytest.raises(DatasetError):
        open_sequence(seq)


def test_truncated_keypoints_npz_is_a_dataset_error(tmp_path):
    out = tmp_path / "seq"
    assert main(["render", "mouse", "-o", str(out), "--frames", "2"]) == 0
    npz = out / "truth" / "keypoints.npz"
    npz.write_bytes(npz.read_bytes()[: npz.stat().st_size // 2])
    with pytest.raises(DatasetError, match="npz"):
        open_sequence(out)


@pytest.mark.parametrize("args, match", [
    (["-o", "x.xyz"], "png"), (["-o", "noext"], "png"), (["-o", "/dev/full"], "png"),
    (["--size", "60000x60000", "-o", "a.png"], "8192"),
])
def test_model_render_bad_outputs_are_one_line(tmp_path, monkeypatch, capsys, args, match):
    monkeypatch.chdir(tmp_path)
    assert main(["model", "render", "two-finger", *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("digiteyes: error:") and match in err[0], err
    assert list(tmp_path.iterdir()) == []


def test_model_render_without_geometry_is_one_line(tmp_path, capsys):
    path = tmp_path / "bare.dh"
    path.write_text("model bare\n[states]\nq0 a angle\n[frames]\n0 - q0 0 1 0 - -\n")
    assert main(["model", "render", str(path), "-o", str(tmp_path / "b.png")]) == 2
    assert "no geometry" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [["track"], ["render"], ["--nope"], ["model", "show"],
                                  ["render", "mouse", "-o", "x", "--frames", "zero"],
                                  ["bench", "nope"], ["evaluate"]])
def test_click_usage_errors_are_one_line(argv, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("digiteyes: error:"), err


# ----------------------------------------------------------------- 8: Python API
def test_public_api_raises_project_errors_naming_the_argument():
    hand = load_model("hand")
    with pytest.raises(StateError, match="quaternion"):
        forward_kinematics(hand, np.zeros(hand.n_q))
    for width, name in ((float("nan"), "width"), (float("inf"), "width"), (None, "width"),
                        ("640", "width"), (0, "width")):
        with pytest.raises(CameraError, match=name):
            Camera.create("c", np.diag([100.0, 100.0, 1.0]), width, 48)
    with pytest.raises(CameraError, match="K"):
        Camera.create("c", "not a matrix", 64, 48)
    with pytest.raises(CameraError, match="depth_mm"):
        Camera.create("c", np.diag([100.0, 100.0, 1.0]), 64, 48, depth_mm=float("nan"))
    for bad in ("x" * 5000, None, 3, "a\0b"):
        with pytest.raises(ModelFileError):
            load_model(bad)
    with pytest.raises(StateError, match="model"):
        forward_kinematics(None, np.zeros(3))
    with pytest.raises(StateError, match="state"):
        forward_kinematics(hand, None)
    with pytest.raises(StateError, match="state"):
        forward_kinematics(hand, 3)


# ----------------------------------------------------------------- 9: video lengths
def _video(path: Path, n: int) -> Path:
    with VideoWriter(path, 10.0) as writer:
        for i in range(n):
            writer.write(np.full((16, 16), 10 * i, dtype=np.uint8))
    return path


def test_videos_of_different_lengths_are_reported_or_refused(tmp_path, capsys):
    a, b = _video(tmp_path / "a.mkv", 3), _video(tmp_path / "b.mkv", 5)
    with pytest.raises(DatasetError, match="differ in length"):
        check_lengths([str(a), str(b)], strict=True)
    longest, warning = check_lengths([str(a), str(b)], strict=False)
    assert longest == 5 and "a.mkv: 3" in warning
    assert "warning" in capsys.readouterr().err
    summary = tmp_path / "summary.json"
    summary.write_text(json.dumps({"frames": 3}))
    assert record_missing(summary, longest, 3, warning) == 2
    payload = json.loads(summary.read_text())
    assert payload["frames_missing"] == 2 and payload["warnings"] == [warning]
    assert check_lengths([str(a), str(a)], strict=True) == (3, None)


def test_truncated_video_counts_missing_frames(tmp_path, capsys):
    path = _video(tmp_path / "a.mkv", 8)
    data = path.read_bytes()
    cut = tmp_path / "cut.mkv"
    cut.write_bytes(data[: len(data) // 2])
    longest, _ = check_lengths([str(path), str(cut)], strict=False)
    assert longest == 8
    with VideoReader(cut) as reader:
        decoded = sum(1 for _ in reader)
    assert decoded < 8


# ----------------------------------------------------------------- 10: state logs
def test_state_log_row_cut_inside_its_last_number_is_dropped(tmp_path):
    model = load_model("two-finger")
    path = tmp_path / "states.csv"
    q = State(model).q + 0.13040102238174398
    with StateLogWriter(path, model) as log:
        for i in range(3):
            log.append(i, q, time_s=0.01, lost=False, residual_rms_px=1.0, iterations=2)
    text = path.read_bytes()
    assert len(read_state_log(path, model)) == 3
    path.write_bytes(text[:-6])  # cut inside the last number of the last row
    log = read_state_log(path, model)
    assert len(log) == 2
    np.testing.assert_array_equal(log.states[-1], q)


# ----------------------------------------------------------------- 11: SIGTERM, temp names
def test_sigterm_becomes_keyboard_interrupt_and_the_handler_is_restored():
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(KeyboardInterrupt), sigterm_as_interrupt():
        os.kill(os.getpid(), signal.SIGTERM)
        signal.sigtimedwait([], 1.0) if hasattr(signal, "sigtimedwait") else None
    assert signal.getsignal(signal.SIGTERM) == before


def test_video_appears_under_its_name_only_when_finalised(tmp_path):
    path = tmp_path / "overlay.mp4"
    writer = VideoWriter(path, 10.0, codec="h264")
    for i in range(3):
        writer.write(np.full((16, 16, 3), 40 * i, dtype=np.uint8))
    assert not path.exists(), "no unplayable video under the final name"
    writer.close()
    assert path.exists() and [p.name for p in tmp_path.iterdir()] == ["overlay.mp4"]
    with VideoReader(path) as reader:
        assert sum(1 for _ in reader) == 3


def test_failed_write_leaves_no_temporary_file(tmp_path):
    def full_disk(tmp: Path) -> None:
        tmp.write_bytes(b"half")
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError), atomic_path(tmp_path / "summary.json") as tmp:
        full_disk(tmp)
    assert list(tmp_path.iterdir()) == []


def test_sigterm_during_a_command_exits_130_in_one_line(tmp_path, monkeypatch, capsys):
    calls = {"n": 0}
    real = digiteyes.synth.sequence.render_views

    def terminated(*a, **k):
        calls["n"] += 1
        if calls["n"] == 2:
            os.kill(os.getpid(), signal.SIGTERM)
        return real(*a, **k)

    monkeypatch.setattr(digiteyes.synth.sequence, "render_views", terminated)
    assert main(["render", "mouse", "-o", str(tmp_path / "s"), "--frames", "4"]) == 130
    assert capsys.readouterr().err.strip().endswith("digiteyes: interrupted")
    assert open_sequence(tmp_path / "s").n_frames >= 1


# ----------------------------------------------------------------- 12: render --video
def test_interrupted_video_render_says_what_works(tmp_path, monkeypatch, capsys):
    real = digiteyes.synth.sequence.render_views
    calls = {"n": 0}

    def interrupted(*a, **k):
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
        return real(*a, **k)

    out = tmp_path / "v"
    monkeypatch.setattr(digiteyes.synth.sequence, "render_views", interrupted)
    assert main(["render", "mouse", "-o", str(out), "--frames", "3", "--video"]) == 130
    err = capsys.readouterr().err
    assert "--force" in err and "--resume to continue" not in err
    monkeypatch.setattr(digiteyes.synth.sequence, "render_views", real)
    assert main(["render", "mouse", "-o", str(out), "--frames", "3", "--video",
                 "--force"]) == 0
    assert open_sequence(out).n_frames == 3


def test_errors_are_digiteyes_errors():
    assert issubclass(DatasetError, DigitEyesError) and io is not None


def test_importing_the_package_loads_no_numeric_code():
    """The command's start (where Ctrl-C must give one line) is inside its guard."""
    code = ("import sys, digiteyes; "
            "assert not {'numpy', 'numba', 'cv2'} & set(sys.modules), sys.modules.keys(); "
            "from digiteyes import forward_kinematics, load_model")
    subprocess.run([sys.executable, "-c", code], check=True,
                   env={**os.environ, "PYTHONPATH": str(Path(digiteyes.__file__).parents[1])})


@pytest.mark.parametrize("delay", [0.5, 1.5])
def test_ctrl_c_in_the_first_seconds_of_track_has_no_traceback(tmp_path, delay):
    env = {**os.environ, "PYTHONPATH": str(Path(digiteyes.__file__).parents[1])}
    process = subprocess.Popen(
        [sys.executable, "-m", "digiteyes.cli", "track", str(tmp_path / "nope.mkv"),
         "--model", "hand", "--rig", str(tmp_path / "r.json"), "--init",
         str(tmp_path / "s.json"), "-o", str(tmp_path / "out")],
        stderr=subprocess.PIPE, env=env)
    time.sleep(delay)
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=120)
    text = err.decode()
    assert "Traceback" not in text, text
    assert process.returncode in (130, 2, -signal.SIGINT), (process.returncode, text)
    assert len(text.strip().splitlines()) <= 1, text


_SIGINT_AT_IMPORT = (
    "import importlib.abc, os, signal, sys, time\n"
    "class Interrupt(importlib.abc.MetaPathFinder):\n"
    "    def find_spec(self, name, path, target=None):\n"
    "        if name == 'digiteyes.commands.track':\n"
    "            os.kill(os.getpid(), signal.SIGINT)\n"
    "            time.sleep(0.5)\n"
    "sys.meta_path.insert(0, Interrupt())\n")
_SIGINT_IN_A_DATACLASS = (
    "import dataclasses, os, signal, time\n"
    "real = dataclasses.Field.__set_name__\n"
    "def interrupted(self, owner, name):\n"
    "    if owner.__module__.startswith('digiteyes.'):\n"
    "        os.kill(os.getpid(), signal.SIGINT)\n"
    "        time.sleep(0.5)\n"
    "    return real(self, owner, name)\n"
    "dataclasses.Field.__set_name__ = interrupted\n")


@pytest.mark.parametrize("interrupt", [_SIGINT_AT_IMPORT, _SIGINT_IN_A_DATACLASS],
                         ids=["at an import", "inside a dataclass"])
def test_ctrl_c_while_the_command_loads_is_one_line(interrupt):
    """A real SIGINT while ``digiteyes.cli`` imports its commands: one line, exit 130.
    Sent at a module's import, or from inside a dataclass field's ``__set_name__``, where
    Python wraps the KeyboardInterrupt a handler would raise in a RuntimeError."""
    code = interrupt + ("import runpy, sys\n"
                        "sys.argv = ['digiteyes', '--help']\n"
                        "runpy.run_module('digiteyes.cli', run_name='__main__')\n")
    env = {**os.environ, "PYTHONPATH": str(Path(digiteyes.__file__).parents[1])}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, env=env,
                          timeout=120)
    text = done.stderr.decode()
    assert "Traceback" not in text, text
    assert done.returncode == 130 and text.strip() == "digiteyes: interrupted", text


def test_ctrl_c_wrapped_by_a_late_import_is_one_line(monkeypatch, capsys):
    from digiteyes import cli

    def wrapped(*args, **kwargs):
        raise RuntimeError("Error calling __set_name__") from KeyboardInterrupt()

    monkeypatch.setattr(cli.cli, "main", wrapped)
    assert cli.main(["--help"]) == 130
    assert capsys.readouterr().err.strip() == "digiteyes: interrupted"


@pytest.mark.parametrize("text", ["\udcffframe,a\n", "frame," + "x" * 200_000 + "\n"])
def test_csv_readers_refuse_undecodable_and_huge_cells(tmp_path, text):
    """Found by the slow fuzz run: bad UTF-8 and over-long cells in state CSVs and logs."""
    model = load_model("hand")
    path = tmp_path / "s.csv"
    path.write_text(text, errors="surrogatepass")
    with pytest.raises(StateError):
        read_states_csv(model, path)
    with pytest.raises(DatasetError):
        read_state_log(path, model)
