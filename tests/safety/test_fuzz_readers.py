"""Fuzzing every reader of user files (issue 12): whatever the bytes, a reader returns or
raises the project's own :class:`~digiteyes.errors.DigitEyesError`, nothing else.

Each reader gets mutations of a valid file (cuts, insertions, replaced sub-trees of its
JSON, random text) and random JSON values. The default suite runs :data:`FAST` cases per
reader; the ``slow``-marked twin runs :data:`SLOW` (``pytest -m slow``).
"""

from __future__ import annotations

import copy
import json
import shutil
import tempfile
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from digiteyes.camera import load_rig
from digiteyes.cli import main
from digiteyes.errors import DigitEyesError
from digiteyes.io import StateLogWriter, open_sequence, read_state_log
from digiteyes.io.dataset import read_ground_truth
from digiteyes.kinematics import State, load_model, parse_model_text, read_states_csv
from digiteyes.models import model_path

FAST = 150
SLOW = 10_000

JSON_VALUES = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=12)
    | st.sampled_from(["../x", "/etc/hostname", "cam0", "png", "video", "{camera}/{index}"]),
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=8), inner,
                                                                max_size=5),
    max_leaves=20)
NASTY = st.sampled_from(["1" + "0" * 400, "9" * 5000, "[" * 3000, "1e999", "NaN", "-0",
                         "\x00", "\udcff", "\ufeff", "{", "\"", "q0", "pi/0", "1deg",
                         "!!opencv-matrix", "rows:", "cols: 99999999", "data: [", "%YAML:1.0",
                         "<opencv_storage>", ",", "\n", "#", "x" * 140_000])


def _paths(node, prefix=()):
    yield prefix
    if isinstance(node, dict):
        for key, value in node.items():
            yield from _paths(value, (*prefix, key))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield from _paths(value, (*prefix, i))


def _replace(node, path, value):
    if not path:
        return value
    node = copy.deepcopy(node)
    parent = node
    for key in path[:-1]:
        parent = parent[key]
    parent[path[-1]] = value
    return node


@st.composite
def near_json(draw, valid: object) -> str:
    """Text of ``valid`` with one sub-tree replaced, a cut, an insertion, or random JSON."""
    how = draw(st.sampled_from(["subtree", "subtree", "cut", "insert", "random"]))
    if how == "subtree":
        paths = list(_paths(valid))
        path = paths[draw(st.integers(0, len(paths) - 1))]
        return json.dumps(_replace(valid, path, draw(JSON_VALUES)))
    if how == "random":
        return json.dumps(draw(JSON_VALUES))
    return draw(near_text(json.dumps(valid)))


@st.composite
def near_text(draw, valid: str) -> str:
    """``valid`` cut short, with a slice replaced by random or nasty text, or random text."""
    how = draw(st.sampled_from(["cut", "insert", "insert", "nasty", "random"]))
    if how == "random":
        return draw(st.text(max_size=200))
    i = draw(st.integers(0, len(valid)))
    if how == "cut":
        return valid[:i]
    j = draw(st.integers(i, min(len(valid), i + 20)))
    middle = draw(NASTY if how == "nasty" else st.text(max_size=20))
    return valid[:i] + middle + valid[j:]


def _check(read: Callable[[], object]) -> None:
    try:
        read()
    except DigitEyesError:
        pass


def _fuzz(n: int):
    return settings(max_examples=n, deadline=None, derandomize=n == FAST,
                    suppress_health_check=list(HealthCheck))


@pytest.fixture(scope="module")
def workdir():
    """A scratch folder with a two-frame rendered sequence (valid files to mutate)."""
    root = Path(tempfile.mkdtemp(prefix="digiteyes-fuzz-"))
    assert main(["render", "mouse", "-o", str(root / "seq"), "--frames", "2"]) == 0
    yield root
    shutil.rmtree(root)


MODEL = load_model("two-finger")
MODEL_TEXT = model_path("two-finger").read_text()
STATE = {"model": MODEL.name, "state": State(MODEL).to_dict()}
RIG = {"cameras": [{"name": "cam0", "width": 64, "height": 48,
                    "K": [[80, 0, 32], [0, 80, 24], [0, 0, 1]], "dist": [0, 0, 0, 0, 0],
                    "rvec": [0.1, 0.2, 0.3], "tvec": [1, 2, 300]}]}
YAML = ("%YAML:1.0\n---\nimage_width: 64\nimage_height: 48\ncamera_matrix: !!opencv-matrix\n"
        "   rows: 3\n   cols: 3\n   dt: d\n   data: [ 80., 0., 32., 0., 80., 24., 0., 0., 1. ]\n"
        "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n"
        "   data: [ 0., 0., 0., 0., 0. ]\n")
XML = ("<?xml version=\"1.0\"?>\n<opencv_storage>\n<image_width>64</image_width>\n"
       "<image_height>48</image_height>\n<camera_matrix type_id=\"opencv-matrix\">\n"
       "  <rows>3</rows>\n  <cols>3</cols>\n  <dt>d</dt>\n"
       "  <data>80. 0. 32. 0. 80. 24. 0. 0. 1.</data></camera_matrix>\n</opencv_storage>\n")


def _state_log_text(tmp: Path) -> str:
    path = tmp / "valid-log.csv"
    with StateLogWriter(path, MODEL) as log:
        for i in range(3):
            log.append(i, State(MODEL).q, time_s=0.01, lost=i == 2, residual_rms_px=0.5,
                       iterations=3)
    return path.read_text()


def _readers(workdir: Path) -> dict[str, tuple[Callable, Callable[[str], None]]]:
    """name -> (strategy of file text, function reading that text)."""
    seq = workdir / "seq"
    scratch = workdir / "scratch"
    scratch.mkdir(exist_ok=True)
    payload = json.loads((seq / "sequence.json").read_text())
    truth_csv = (seq / "truth" / "states.csv").read_text()
    mouse = load_model(str(seq / "model.dh"))

    def at(name: str, text: str) -> Path:
        path = scratch / name
        path.write_text(text, encoding="utf-8", errors="surrogatepass")
        return path

    def sequence(text: str) -> None:
        (seq / "sequence.json").write_text(text, encoding="utf-8", errors="surrogatepass")
        _check(lambda: open_sequence(seq).close())

    def truth(text: str) -> None:
        at("truth.csv", text)
        _check(lambda: read_ground_truth(scratch, {"states": "truth.csv"}, mouse, 1, 2))

    def yaml(text: str) -> None:
        path = at("calib.yml", text)
        _check(lambda: load_rig(path))

    def xml(text: str) -> None:
        path = at("calib.xml", text)
        _check(lambda: load_rig(path))

    return {
        "model": (near_text(MODEL_TEXT), lambda t: _check(lambda: parse_model_text(t))),
        "state-json": (near_json(STATE),
                       lambda t: _check(lambda: State.load_json(MODEL, at("s.json", t)))),
        "state-csv": (near_text("frame," + ",".join(MODEL.state_names) + "\n0,"
                                + ",".join(map(repr, State(MODEL).q)) + "\n"),
                      lambda t: _check(lambda: read_states_csv(MODEL, at("s.csv", t)))),
        "rig-json": (near_json(RIG), lambda t: _check(lambda: load_rig(at("rig.json", t)))),
        "opencv-yaml": (near_text(YAML), yaml),
        "opencv-xml": (near_text(XML), xml),
        "sequence-json": (near_json(payload), sequence),
        "truth-states": (near_text(truth_csv), truth),
        "state-log": (near_text(_state_log_text(scratch)),
                      lambda t: _check(lambda: read_state_log(at("log.csv", t), MODEL))),
    }


READERS = ["model", "state-json", "state-csv", "rig-json", "opencv-yaml", "opencv-xml",
           "sequence-json", "truth-states", "state-log"]


def _run(workdir: Path, reader: str, n: int) -> None:
    strategy, read = _readers(workdir)[reader]
    original = (workdir / "seq" / "sequence.json").read_text()

    @_fuzz(n)
    @given(strategy)
    def case(text: str) -> None:
        read(text)

    try:
        case()
    finally:
        (workdir / "seq" / "sequence.json").write_text(original)


@pytest.mark.parametrize("reader", READERS)
def test_reader_raises_only_project_errors(workdir, reader):
    _run(workdir, reader, FAST)


@pytest.mark.slow
@pytest.mark.parametrize("reader", READERS)
def test_reader_raises_only_project_errors_at_length(workdir, reader):
    _run(workdir, reader, SLOW)


def _npz_bytes(seq: Path) -> bytes:
    return (seq / "truth" / "keypoints.npz").read_bytes()


def _fuzz_npz(workdir: Path, n: int) -> None:
    seq = workdir / "seq"
    original = _npz_bytes(seq)
    path = seq / "truth" / "keypoints.npz"
    mouse = load_model(str(seq / "model.dh"))

    @_fuzz(n)
    @given(st.integers(0, len(original)), st.binary(max_size=16), st.booleans())
    def case(i: int, junk: bytes, cut: bool) -> None:
        path.write_bytes(original[:i] if cut else original[:i] + junk + original[i + len(junk):])
        _check(lambda: read_ground_truth(seq, {"keypoints": "truth/keypoints.npz"}, mouse,
                                         1, 2))

    try:
        case()
    finally:
        path.write_bytes(original)
    assert zipfile.is_zipfile(path) and np.load(path)["names"].size


def test_truth_keypoints_npz_raises_only_project_errors(workdir):
    _fuzz_npz(workdir, FAST)


@pytest.mark.slow
def test_truth_keypoints_npz_raises_only_project_errors_at_length(workdir):
    _fuzz_npz(workdir, SLOW)
