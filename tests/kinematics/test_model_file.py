"""The model-file parser: the grammar, every error case, and fuzzing for stray exceptions.

Each malformed input must raise :class:`ModelFileError` whose message starts with
``FILE:LINE:`` and says what was wrong; no other exception may escape the parser or the
model builder, whatever the text (property tests at the end).
"""

from __future__ import annotations

import math
import re
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from digiteyes.errors import ModelFileError
from digiteyes.kinematics import (
    KinematicModel,
    forward_kinematics,
    model_from_file,
    parse_model_text,
)
from digiteyes.kinematics.model_file import parse_value, read_model_file
from digiteyes.models import MODEL_DIR

# A valid two-link planar arm; the error cases below edit one line of it. Line numbers:
# 1 header, 2 [states], 3-4 states, 5 [frames], 6-9 frames.
ARM = """\
model arm
[states]
q0  shoulder  angle  -90deg  90deg
q1  elbow     angle  0deg    150deg
[frames]
0   base      0      0  0    0  box(40,40,20)  1
1   upper     q0     0  300  0  cyl(30)        2
2   fore      q1     0  250  0  cyl(25)        3
3   hand      0      0  0    0  tip(30)        -
"""
FILE_NAME = "bad.dh"
HAND_TEXT = (MODEL_DIR / "hand.dh").read_text(encoding="utf-8")
FUZZ = settings(
    max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)


def edit(line: int, new: str, text: str = ARM) -> str:
    """``text`` with its 1-based ``line`` replaced by ``new`` (several lines allowed)."""
    lines = text.splitlines()
    lines[line - 1] = new
    return "\n".join(lines) + "\n"


def build(text: str, path: str = FILE_NAME) -> KinematicModel:
    return KinematicModel(parse_model_text(text, path))


# ---------------------------------------------------------------------------- valid input
def test_arm_parses_into_the_documented_tree() -> None:
    model = build(ARM)
    assert model.name == "arm"
    assert model.n_q == model.n_v == 2
    assert model.state_names == ("shoulder", "elbow")
    assert list(model.parent) == [-1, 0, 1, 2]
    assert [link.kind for link in model.links] == ["palm", "link", "link", "tip"]
    assert model.link("upper").length == 300.0
    assert model.link("fore").radius == 25.0
    np.testing.assert_allclose(model.lower, np.radians([-90.0, 0.0]))
    np.testing.assert_allclose(model.upper, np.radians([90.0, 150.0]))


@pytest.mark.parametrize(
    ("token", "value"),
    [
        ("12", 12.0),
        ("-12.5", -12.5),
        ("+.5", 0.5),
        ("5.", 5.0),
        ("1e3", 1000.0),
        ("2.5E-1", 0.25),
        ("pi", math.pi),
        ("-pi", -math.pi),
        ("pi/2", math.pi / 2),
        ("-pi/4", -math.pi / 4),
        ("2*pi/3", 2 * math.pi / 3),
        ("0.5*pi", math.pi / 2),
        ("30deg", math.radians(30.0)),
        ("-25deg", math.radians(-25.0)),
    ],
)
def test_number_syntax(token: str, value: float) -> None:
    assert parse_value(token) == pytest.approx(value)


@pytest.mark.parametrize(
    "token", ["", "abc", "1.2.3", "pi/0", "2pi", "pi*2", "deg", "30 deg", "30rad", "1/2", "--1",
              "nan", "inf", "pi/-2", "1e", "0x10"],
)
def test_bad_numbers_raise_value_error(token: str) -> None:
    with pytest.raises(ValueError):
        parse_value(token)


def test_comments_blank_lines_tabs_and_description() -> None:
    text = ARM.replace("model arm\n", "# a comment line\n\nmodel arm   # trailing\n"
                       "description a two-link arm  # not part of it\n")
    text = text.replace("1   upper     q0", "1\tupper\tq0")
    model = build(text)
    assert model.description == "a two-link arm"
    assert model.link("upper").length == 300.0


def test_section_names_ignore_case_and_padding() -> None:
    model = build(ARM.replace("[states]", "[ STATES ]").replace("[frames]", "[Frames]"))
    assert model.n_frames == 4


def test_rows_may_come_in_any_order() -> None:
    lines = ARM.splitlines()
    text = "\n".join([*lines[:5], *reversed(lines[5:])])
    assert list(build(text).parent) == [-1, 0, 1, 2]


def test_pose_root_and_prismatic_joint() -> None:
    text = """\
model slider
[states]
q0 base.qw quat
q1 base.qx quat
q2 base.qy quat
q3 base.qz quat
q4 base.x trans
q5 base.y trans
q6 base.z trans -100 100
q7 slide length 0 50
[frames]
0 base pose:q0 0 0 0 box(10,10,10) 1
1 rail 0 q7 20 0 cyl(5) 2
2 - 0 0 0 0 - -
"""
    model = build(text)
    assert model.base_state == 0
    assert (model.n_q, model.n_v) == (8, 7)
    assert model.d_state[1] == 7
    assert model.upper[6] == 100.0
    assert model.tangent_names[:3] == ("base.rx", "base.ry", "base.rz")


def test_box_with_three_sizes_is_centred_on_the_shape_frame() -> None:
    palm = build(ARM).link("base")
    assert palm.size == (40.0, 40.0, 20.0)
    assert palm.centre == (0.0, 0.0, 0.0)


def test_worked_example_in_the_docs(tmp_path: Path) -> None:
    """The arm of docs/models.md loads and puts its hand where the text says."""
    docs = (Path(__file__).parents[2] / "docs" / "models.md").read_text(encoding="utf-8")
    block = docs.split("<!-- example: arm.dh", 1)[1].split("```text\n", 1)[1].split("```", 1)[0]
    path = tmp_path / "arm.dh"
    path.write_text(block, encoding="utf-8")
    arm = model_from_file(path)
    assert arm.describe().startswith("model arm: two-link planar arm")
    tips, _ = forward_kinematics(arm, np.radians([90.0, 90.0])).tip_centres()
    np.testing.assert_allclose(tips, [[-250.0, 300.0, 0.0]], atol=1e-9)


# ---------------------------------------------------------------------------- error cases
QUATERNION_ONLY = """\
model spinner
[states]
q0 w quat
q1 x quat
q2 y quat
q3 z quat
[frames]
0 - pose:q0 0 0 0 - -
"""
# Frames 0-2 form the tree; frames 3 and 4 point at each other.
SIDE_CYCLE = edit(8, "2 fore q1 0 250 0 cyl(25) -", edit(9, "3 hand 0 0 0 0 tip(30) 4")) + (
    "4 - 0 0 0 0 - 3\n"
)
# (id, text, expected line or None, regex for the message after "FILE:LINE: ")
ERROR_CASES = [
    ("missing header", ARM.replace("model arm\n", ""), None, r"missing header line 'model NAME'"),
    ("empty model name", edit(1, "model"), 1, r"expected 'model NAME'"),
    ("junk before sections", edit(1, "model arm\nhello"), 2, r"expected 'model NAME'.*'hello'"),
    ("bad section", edit(2, "[joints]"), 2, r"unknown section \[joints\]"),
    ("no frames", ARM.split("[frames]")[0], None, r"no \[frames\] rows"),
    ("short state row", edit(3, "q0 shoulder"), 3, r"state row needs .* got 2 cells"),
    ("state row with one limit", edit(3, "q0 shoulder angle -90deg"), 3,
     r"state row needs .* got 4 cells"),
    ("bad state index", edit(3, "x0 shoulder angle"), 3, r"state index must look like q7"),
    ("bad state kind", edit(3, "q0 shoulder hinge"), 3, r"state kind must be one of"),
    ("bad lower limit", edit(3, "q0 shoulder angle low 90deg"), 3,
     r"lower limit must be a number.*'low'"),
    ("limits lower = upper", edit(3, "q0 shoulder angle 1 1"), 3, r"lower limit 1 is not below 1"),
    ("limits lower > upper", edit(3, "q0 shoulder angle 90deg -90deg"), 3,
     r"lower limit 90deg is not below -90deg"),
    ("infinite limit", edit(3, "q0 shoulder angle -1e999 1"), 3, r"lower limit must be finite"),
    ("quaternion with limits", edit(3, "q0 shoulder quat -1 1"), 3,
     r"quaternion states take no limits"),
    ("short frame row", edit(7, "1 upper q0 0 300 0 cyl(30)"), 7,
     r"frame row needs 8 cells .* got 7"),
    ("frame number not an integer", edit(7, "one upper q0 0 300 0 cyl(30) 2"), 7,
     r"frame number must be an integer, got 'one'"),
    ("bad theta", edit(7, "1 upper 1.2.3 0 300 0 cyl(30) 2"), 7,
     r"theta must be a number.*'1\.2\.3'"),
    ("bad d", edit(7, "1 upper q0 x 300 0 cyl(30) 2"), 7, r"d must be a number.*'x'"),
    ("bad a", edit(7, "1 upper q0 0 3OO 0 cyl(30) 2"), 7, r"a must be a number.*'3OO'"),
    ("bad alpha", edit(7, "1 upper q0 0 300 pi/0 cyl(30) 2"), 7, r"alpha must be a number"),
    ("non-finite a", edit(7, "1 upper q0 0 1e400 0 cyl(30) 2"), 7, r"a must be finite"),
    ("bad pose reference", edit(6, "0 base pose:x 0 0 0 - 1"), 6,
     r"theta pose:qK must name a state like q7, got 'x'"),
    ("bad next", edit(7, "1 upper q0 0 300 0 cyl(30) two"), 7,
     r"'next' must list frame numbers or '-', got 'two'"),
    ("next mixes '-' and numbers", edit(7, "1 upper q0 0 300 0 cyl(30) - 2"), 7,
     r"'next' must list frame numbers or '-'"),
    ("unknown shape", edit(9, "3 hand 0 0 0 0 sphere(30) -"), 9, r"shape must be '-', box"),
    ("shape with spaces", edit(9, "3 hand 0 0 0 0 box(1, 2, 3) -"), 9,
     r"shape must be .*'box\(1,'"),
    ("shape arity", edit(8, "2 fore q1 0 250 0 cyl(25,3) 3"), 8, r"shape must be .*'cyl\(25,3\)'"),
    ("box arity", edit(6, "0 base 0 0 0 0 box(1,2,3,4) 1"), 6, r"shape must be .*box\(1,2,3,4\)"),
    ("bad shape number", edit(8, "2 fore q1 0 250 0 cyl(r) 3"), 8,
     r"cyl parameter must be a number"),
    ("zero radius", edit(8, "2 fore q1 0 250 0 cyl(0) 3"), 8, r"shape sizes must be positive"),
    ("negative tip radius", edit(9, "3 hand 0 0 0 0 tip(-3) -"), 9,
     r"shape sizes must be positive"),
    ("zero box size", edit(6, "0 base 0 0 0 0 box(40,0,20) 1"), 6, r"shape sizes must be positive"),
    ("cyl with a = 0", edit(8, "2 fore q1 0 0 0 cyl(25) 3"), 8,
     r"a cyl\(\) link needs a positive length a"),
    ("cyl with a < 0", edit(8, "2 fore q1 0 -250 0 cyl(25) 3"), 8,
     r"a cyl\(\) link needs a positive length a"),
    ("state gap", edit(4, "q2 elbow angle 0deg 150deg"), 4,
     r"states must be numbered q0\.\.q1 .* expected q1, got q2"),
    ("state repeated", edit(4, "q0 elbow angle 0deg 150deg"), 4,
     r"states must be numbered .* expected q1, got q0"),
    ("state name repeated", edit(4, "q1 shoulder angle 0deg 150deg"), 4,
     r"state name 'shoulder' repeats \(first on line 3\)"),
    ("unknown state", edit(8, "2 fore q5 0 250 0 cyl(25) 3"), 8,
     r"q5 is not declared in \[states\]"),
    ("state used twice", edit(8, "2 fore q0 0 250 0 cyl(25) 3"), 8,
     r"q0 is already used by the row on line 7"),
    ("unused state", edit(8, "2 fore 0 0 250 0 cyl(25) 3"), 4,
     r"q1 is declared but no row uses it"),
    ("angle used as d", edit(8, "2 fore 0 q1 250 0 cyl(25) 3"), 8,
     r"q1 is declared as 'angle' but used as 'length'"),
    ("theta and d both states", edit(8, "2 fore q1 q1 250 0 cyl(25) 3"), 8,
     r"a row may have one joint: theta or d, not both"),
    ("pose and d state", edit(6, "0 base pose:q0 q1 0 0 - 1"), 6,
     r"a row may have one joint: theta or d"),
    ("pose on a non-root row", edit(8, "2 fore pose:q1 0 250 0 cyl(25) 3"), 8,
     r"only the root row may have pose:qK"),
    ("pose on angle states", edit(6, "0 base pose:q0 0 0 0 - 1"), 6,
     r"q0 is declared as 'angle' but used as 'quat'"),
    ("pose beyond the declared states", QUATERNION_ONLY, 8, r"q4 is not declared in \[states\]"),
    ("frame gap", edit(9, "4 hand 0 0 0 0 tip(30) -"), 9,
     r"frames must be numbered 0\.\.3 .* expected 3, got 4"),
    ("frame repeated", edit(9, "2 hand 0 0 0 0 tip(30) -"), 9,
     r"frames must be numbered .* expected 3, got 2"),
    ("dangling next", edit(9, "3 hand 0 0 0 0 tip(30) 7"), 9, r"next frame 7 does not exist"),
    ("self loop", edit(9, "3 hand 0 0 0 0 tip(30) 3"), 9, r"frame 3 is reached twice"),
    ("two parents", edit(9, "3 hand 0 0 0 0 tip(30) 1"), 9, r"frame 1 is reached twice"),
    ("two roots", edit(8, "2 fore q1 0 250 0 cyl(25) -"), 9,
     r"the frames must form one tree with one root; found roots \[0, 3\]"),
    ("cycle apart from the tree", SIDE_CYCLE, 9, r"frame 3 is in a cycle"),
    ("repeated geometry name", edit(8, "2 upper q1 0 250 0 cyl(25) 3"), 8,
     r"geometry name 'upper' repeats \(first on line 7\)"),
]


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [case[1:] for case in ERROR_CASES],
    ids=[case[0] for case in ERROR_CASES],
)
def test_malformed_file_names_file_line_and_problem(
    tmp_path: Path, text: str, line: int | None, message: str
) -> None:
    path = tmp_path / FILE_NAME
    path.write_text(text, encoding="utf-8")
    where = re.escape(str(path)) + (f":{line}" if line is not None else "")
    with pytest.raises(ModelFileError, match=f"^{where}: {message}") as info:
        model_from_file(path)
    assert info.value.path == str(path)
    assert info.value.line == line


def test_cycle_through_the_root_names_a_line() -> None:
    """With every frame listed in some 'next' cell there is no root; the error still points
    at a row (the one that lists frame 0)."""
    text = edit(9, "3 hand 0 0 0 0 tip(30) 0")
    with pytest.raises(ModelFileError, match=rf"^{FILE_NAME}:\d+: ") as info:
        build(text)
    assert info.value.line is not None


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "none.dh"
    with pytest.raises(ModelFileError, match=f"^{re.escape(str(path))}: no such model file"):
        read_model_file(path)


def test_directory_is_unreadable(tmp_path: Path) -> None:
    with pytest.raises(ModelFileError, match=f"^{re.escape(str(tmp_path))}: cannot read"):
        read_model_file(tmp_path)


def test_non_utf8_file_is_unreadable(tmp_path: Path) -> None:
    path = tmp_path / "latin1.dh"
    path.write_bytes(ARM.replace("arm", "bras \xe0 deux").encode("latin-1"))
    with pytest.raises(ModelFileError, match=f"^{re.escape(str(path))}: cannot read"):
        read_model_file(path)


# ------------------------------------------- odd input that must not escape as other errors
@pytest.mark.parametrize(
    ("text", "line"),
    [
        (edit(9, "\u00b2 hand 0 0 0 0 tip(30) -"), 9),  # superscript two passes str.isdigit
        (edit(9, "3 hand 0 0 0 0 tip(30) \u2460"), 9),  # circled one passes str.isdigit
        (edit(9, "3" * 5000 + " hand 0 0 0 0 tip(30) -"), 9),  # int() digit limit
        (edit(8, "2 fore q" + "1" * 5000 + " 0 250 0 cyl(25) 3"), 8),
        (edit(4, "q" + "1" * 5000 + " elbow angle"), 4),
    ],
    ids=["superscript frame", "circled next", "huge frame", "huge theta state", "huge state"],
)
def test_odd_integers_raise_model_file_error(text: str, line: int) -> None:
    with pytest.raises(ModelFileError, match=rf"^{FILE_NAME}:{line}: "):
        build(text)


def test_describe_survives_a_deep_chain() -> None:
    """A chain deeper than Python's recursion limit still describes itself."""
    n = 1500
    rows = "\n".join(f"{i} - 0 0 1 0 - {i + 1 if i < n - 1 else '-'}" for i in range(n))
    model = build(f"model chain\n[frames]\n{rows}\n")
    assert f"{n - 1}" in model.describe()


def test_path_with_nul_byte_raises_model_file_error() -> None:
    with pytest.raises(ModelFileError):
        read_model_file("bad\0name.dh")


def test_header_may_use_a_tab() -> None:
    assert build(ARM.replace("model arm", "model\tarm")).name == "arm"


@pytest.mark.parametrize("shape", ["box(40,,40,20)", "box(40,40,20,)", "tip(,25)"])
def test_empty_shape_arguments_are_rejected(shape: str) -> None:
    with pytest.raises(ModelFileError, match=rf"^{FILE_NAME}:6: shape must be"):
        build(edit(6, f"0 base 0 0 0 0 {shape} 1"))


# ------------------------------------------------------------------------ property tests
def expect_model_or_model_file_error(text: str) -> None:
    """Parse and build ``text``: success or ModelFileError, never any other exception."""
    try:
        model = build(text, "fuzz.dh")
    except ModelFileError as exc:
        assert str(exc).startswith("fuzz.dh")
        return
    assert model.describe()


GRAMMAR_TOKENS = [
    "model", "description", "[states]", "[frames]", "[", "]", "#", "-", "q0", "q1", "q2", "q7",
    "q99", "pose:q0", "pose:", "quat", "trans", "angle", "length", "0", "1", "2", "3", "10",
    "-1", "pi", "-pi/2", "2*pi/3", "30deg", "1e999", "box(1,2,3)", "box(1,2,3,4,5,6)", "cyl(5)",
    "tip(2)", "cyl(0)", "box(", "0.5", "palm", "x.y",
]
cells = st.one_of(st.sampled_from(GRAMMAR_TOKENS), st.text(min_size=1, max_size=6))
lines = st.lists(cells, max_size=10).map(" ".join)


@FUZZ
@given(st.text(max_size=400))
def test_arbitrary_text_raises_only_model_file_error(text: str) -> None:
    expect_model_or_model_file_error(text)


@FUZZ
@given(st.lists(lines, max_size=12))
def test_token_soup_raises_only_model_file_error(body: list[str]) -> None:
    expect_model_or_model_file_error("model soup\n" + "\n".join(body))


@st.composite
def mutated_hand(draw: st.DrawFn) -> str:
    """hand.dh after a few random line deletions, duplications, token swaps or a truncation."""
    rows = HAND_TEXT.splitlines()
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["delete", "duplicate", "swap", "replace", "truncate"]))
        if not rows:
            break
        i = draw(st.integers(0, len(rows) - 1))
        if op == "delete":
            del rows[i]
        elif op == "duplicate":
            rows.insert(draw(st.integers(0, len(rows))), rows[i])
        elif op == "truncate":
            text = "\n".join(rows)
            rows = text[: draw(st.integers(0, len(text)))].splitlines()
        else:
            tokens = rows[i].split()
            if len(tokens) < 2:
                continue
            j, k = draw(st.integers(0, len(tokens) - 1)), draw(st.integers(0, len(tokens) - 1))
            if op == "swap":
                tokens[j], tokens[k] = tokens[k], tokens[j]
            else:
                tokens[j] = draw(cells)
            rows[i] = " ".join(tokens)
    return "\n".join(rows)


@FUZZ
@given(mutated_hand())
def test_mutated_hand_raises_only_model_file_error(text: str) -> None:
    expect_model_or_model_file_error(text)


@FUZZ
@given(st.binary(max_size=300))
def test_arbitrary_bytes_on_disk_raise_only_model_file_error(data: bytes) -> None:
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "fuzz.dh"
        path.write_bytes(data)
        try:
            model_from_file(path)
        except ModelFileError as exc:
            assert str(exc).startswith(str(path))


@FUZZ
@given(st.text(max_size=30))
def test_parse_value_raises_only_value_error(token: str) -> None:
    try:
        value = parse_value(token)
    except ValueError:
        return
    assert isinstance(value, float)
