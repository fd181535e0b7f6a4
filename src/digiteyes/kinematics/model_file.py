"""Parser for digiteyes model files (format 1), the text form of thesis Table 2.1.

A model file has a header (``model NAME``, optional ``description ...``), a ``[states]``
section naming every state variable with its kind and optional limits, and a ``[frames]``
section whose rows mirror the thesis table::

    # frame  geometry        theta    d    a    alpha   shape        next
    0        palm            pose:q0  0    0    0       box(56,86,15) 1 8
    1        -               pi/2     0    38   -pi/2   -            2
    4        index.proximal  q8       0    45   0       cyl(10)      5

Numbers accept ``pi`` forms (``pi/2``, ``-pi``, ``2*pi/3``) and degrees (``30deg``).
``theta`` or ``d`` (not both) may name a state (``q8``): a revolute or prismatic joint.
``pose:qK`` on the root row makes it a base node with a 7-state spatial transform: a unit
quaternion (w, x, y, z) in ``qK..qK+3`` and a translation in ``qK+4..qK+6``. See
docs/models.md for the full grammar. Every error names the file, the line and what was
expected (:class:`~digiteyes.errors.ModelFileError`).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

from digiteyes.errors import ModelFileError

STATE_KINDS = ("quat", "trans", "angle", "length")

_NUMBER = r"(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_VALUE_RE = re.compile(
    rf"^(?P<sign>[-+])?(?:(?P<num>{_NUMBER})(?P<deg>deg)?|(?:(?P<mul>{_NUMBER})\*)?pi"
    rf"(?:/(?P<div>{_NUMBER}))?)$"
)
_STATE_RE = re.compile(r"^q([0-9]{1,9})$")
_INDEX_RE = re.compile(r"^[0-9]{1,9}$")
_SHAPE_RE = re.compile(r"^(?P<kind>box|cyl|tip|edge)\((?P<args>[^()]*)\)$")
_SHAPE_ARITY = {"box": (3, 6), "cyl": (1, 1), "tip": (1, 1), "edge": (1, 1)}


@dataclass(frozen=True)
class StateSpec:
    """One declared state variable: index, name, kind and limits (radians or mm)."""

    index: int
    name: str
    kind: str
    lower: float
    upper: float
    line: int


@dataclass(frozen=True)
class ShapeSpec:
    """Geometry of a row: ``box`` (palm slab), ``cyl`` (link), ``tip`` (sphere) or ``edge``.

    ``params`` are millimetres: box = (size_x, size_y, size_z, centre_x, centre_y, centre_z)
    in the shape frame, cyl = (radius,), tip = (radius,), edge = (radius,). An ``edge`` is a
    rounded edge of another body (e.g. the palm slab): tracked like a cylinder link, but not
    a body of its own (not rendered, labelled or given a keypoint).
    """

    kind: str
    params: tuple[float, ...]


@dataclass(frozen=True)
class FrameSpec:
    """One row of the frame table, as written in the file."""

    index: int
    geometry: str | None
    theta: float
    theta_state: int | None
    d: float
    d_state: int | None
    a: float
    alpha: float
    pose_state: int | None
    shape: ShapeSpec | None
    next: tuple[int, ...]
    line: int


@dataclass(frozen=True)
class ModelSpec:
    """The parsed content of a model file, before any topology checks."""

    name: str
    description: str
    states: tuple[StateSpec, ...]
    frames: tuple[FrameSpec, ...]
    path: str


def parse_value(token: str) -> float:
    """Parse a number cell: ``12.5``, ``-pi/2``, ``2*pi/3``, ``30deg``. Raises ValueError."""
    match = _VALUE_RE.match(token)
    if match is None:
        raise ValueError(token)
    sign = -1.0 if match["sign"] == "-" else 1.0
    if match["num"] is not None:
        value = float(match["num"])
        if match["deg"]:
            value = math.radians(value)
        return sign * value
    value = math.pi * (float(match["mul"]) if match["mul"] else 1.0)
    if match["div"]:
        divisor = float(match["div"])
        if divisor == 0.0:
            raise ValueError(token)
        value /= divisor
    return sign * value


def read_model_file(path: str | Path) -> ModelSpec:
    """Read and parse a model file from disk."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ModelFileError(str(path), None, "no such model file") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise ModelFileError(str(path), None, f"cannot read model file ({exc})") from None
    return parse_model_text(text, str(path))


MAX_MODEL_CHARS = 1_000_000
"""Longest model file read (characters); the shipped hand model is 4 kB."""
MAX_MODEL_FRAMES = 2_000
"""Most ``[frames]`` rows a model may have (the hand has 60)."""


def _shown(text: str, limit: int = 40) -> str:
    """``text`` quoted for an error message, cut to ``limit`` characters."""
    return repr(text) if len(text) <= limit else repr(text[:limit]) + "..."


def parse_model_text(text: str, path: str = "<string>") -> ModelSpec:
    """Parse model-file text; ``path`` is used in error messages only.

    Files longer than :data:`MAX_MODEL_CHARS` or with more than :data:`MAX_MODEL_FRAMES`
    frame rows are refused (:class:`~digiteyes.errors.ModelFileError`).
    """
    if not isinstance(text, str):
        raise ModelFileError(str(path), None, f"model text must be a str, got "
                                              f"{type(text).__name__}")
    if len(text) > MAX_MODEL_CHARS:
        raise ModelFileError(path, None, f"model file is longer than {MAX_MODEL_CHARS} "
                                         "characters")
    name: str | None = None
    description = ""
    section: str | None = None
    states: list[StateSpec] = []
    frames: list[FrameSpec] = []
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith("[") and line.endswith("]"):
            section = line[1:-1].strip().lower()
            if section not in ("states", "frames"):
                raise ModelFileError(
                    path, number, f"unknown section [{section}]; expected [states] or [frames]"
                )
            continue
        if section is None:
            key, _, rest = line.replace("\t", " ").partition(" ")
            if key == "model" and rest.strip():
                name = rest.strip()
            elif key == "description":
                description = rest.strip()
            else:
                raise ModelFileError(
                    path,
                    number,
                    f"expected 'model NAME', 'description TEXT' or a section, got {_shown(line)}",
                )
        elif section == "states":
            states.append(_parse_state_row(line.split(), path, number))
        else:
            frames.append(_parse_frame_row(line.split(), path, number))
            if len(frames) > MAX_MODEL_FRAMES:
                raise ModelFileError(path, number, f"more than {MAX_MODEL_FRAMES} frame rows")
    if name is None:
        raise ModelFileError(path, None, "missing header line 'model NAME'")
    if not frames:
        raise ModelFileError(path, None, "no [frames] rows: a model needs at least one frame")
    return ModelSpec(name, description, tuple(states), tuple(frames), path)


def _parse_state_row(cells: list[str], path: str, line: int) -> StateSpec:
    if len(cells) not in (3, 5):
        raise ModelFileError(
            path, line, f"state row needs 'qK NAME KIND [LOWER UPPER]', got {len(cells)} cells"
        )
    match = _STATE_RE.match(cells[0])
    if match is None:
        raise ModelFileError(path, line, f"state index must look like q7, got {_shown(cells[0])}")
    kind = cells[2]
    if kind not in STATE_KINDS:
        raise ModelFileError(
            path, line, f"state kind must be one of {', '.join(STATE_KINDS)}, got {_shown(kind)}"
        )
    lower, upper = -math.inf, math.inf
    if len(cells) == 5:
        if kind == "quat":
            raise ModelFileError(path, line, "quaternion states take no limits")
        lower = _value(cells[3], "lower limit", path, line)
        upper = _value(cells[4], "upper limit", path, line)
        if not lower < upper:
            raise ModelFileError(path, line, f"lower limit {cells[3]} is not below {cells[4]}")
    return StateSpec(int(match[1]), cells[1], kind, lower, upper, line)


def _parse_frame_row(cells: list[str], path: str, line: int) -> FrameSpec:
    if len(cells) < 8:
        raise ModelFileError(
            path,
            line,
            "frame row needs 8 cells 'frame geometry theta d a alpha shape next...', "
            f"got {len(cells)}",
        )
    if not _INDEX_RE.match(cells[0]):
        raise ModelFileError(path, line, f"frame number must be an integer, got {_shown(cells[0])}")
    geometry = None if cells[1] == "-" else cells[1]
    pose_state = theta_state = d_state = None
    theta = d = 0.0
    if cells[2].startswith("pose:"):
        pose_state = _state_ref(cells[2][5:], "theta pose:qK", path, line)
    elif _STATE_RE.match(cells[2]):
        theta_state = _state_ref(cells[2], "theta", path, line)
    else:
        theta = _value(cells[2], "theta", path, line)
    if _STATE_RE.match(cells[3]):
        d_state = _state_ref(cells[3], "d", path, line)
    else:
        d = _value(cells[3], "d", path, line)
    if d_state is not None and (theta_state is not None or pose_state is not None):
        raise ModelFileError(path, line, "a row may have one joint: theta or d, not both")
    a = _value(cells[4], "a", path, line)
    alpha = _value(cells[5], "alpha", path, line)
    shape = None if cells[6] == "-" else _parse_shape(cells[6], path, line)
    nexts: list[int] = []
    if cells[7:] != ["-"]:
        for cell in cells[7:]:
            if not _INDEX_RE.match(cell):
                raise ModelFileError(
                    path, line, f"'next' must list frame numbers or '-', got {_shown(cell)}"
                )
            nexts.append(int(cell))
    return FrameSpec(
        int(cells[0]), geometry, theta, theta_state, d, d_state, a, alpha, pose_state, shape,
        tuple(nexts), line,
    )


def _parse_shape(cell: str, path: str, line: int) -> ShapeSpec:
    match = _SHAPE_RE.match(cell)
    expected = ("shape must be '-', box(sx,sy,sz[,cx,cy,cz]), cyl(radius), tip(radius) or "
                "edge(radius)")
    if match is None:
        raise ModelFileError(path, line, f"{expected}; got {_shown(cell)}")
    kind = match["kind"]
    args = match["args"].split(",")
    low, high = _SHAPE_ARITY[kind]
    if len(args) not in (low, high):
        raise ModelFileError(path, line, f"{expected}; got {_shown(cell)}")
    params = tuple(_value(arg, f"{kind} parameter", path, line) for arg in args)
    if kind == "box" and len(params) == 3:
        params = (*params, 0.0, 0.0, 0.0)
    sizes = params[:3] if kind == "box" else params
    if any(not size > 0.0 for size in sizes):
        raise ModelFileError(path, line, f"shape sizes must be positive, got {_shown(cell)}")
    return ShapeSpec(kind, params)


def _value(token: str, what: str, path: str, line: int) -> float:
    try:
        value = parse_value(token)
    except ValueError:
        raise ModelFileError(
            path, line, f"{what} must be a number, pi expression or NNdeg, got {_shown(token)}"
        ) from None
    if not math.isfinite(value):
        raise ModelFileError(path, line, f"{what} must be finite, got {_shown(token)}")
    return value


def _state_ref(token: str, what: str, path: str, line: int) -> int:
    match = _STATE_RE.match(token)
    if match is None:
        raise ModelFileError(path, line, f"{what} must name a state like q7, got {_shown(token)}")
    return int(match[1])


def _format_number(value: float) -> str:
    return repr(float(value)) if value != 0.0 else "0"


def format_model_text(spec: ModelSpec) -> str:
    """Write a :class:`ModelSpec` as model-file text that parses back to the same numbers.

    Numbers are written at full precision (``repr``), limits in radians or mm, so a
    perturbed model (e.g. the "true" hand of a rendered dataset) can be saved exactly.
    """
    lines = [f"model {spec.name}"]
    if spec.description:
        lines.append(f"description {spec.description}")
    lines += ["", "[states]", "# index  name  kind  lower  upper"]
    for state in sorted(spec.states, key=lambda s: s.index):
        row = f"q{state.index}  {state.name}  {state.kind}"
        if math.isfinite(state.lower) or math.isfinite(state.upper):
            row += f"  {_format_number(state.lower)}  {_format_number(state.upper)}"
        lines.append(row)
    lines += ["", "[frames]", "# frame  geometry  theta  d  a  alpha  shape  next"]
    for frame in sorted(spec.frames, key=lambda f: f.index):
        if frame.pose_state is not None:
            theta = f"pose:q{frame.pose_state}"
        elif frame.theta_state is not None:
            theta = f"q{frame.theta_state}"
        else:
            theta = _format_number(frame.theta)
        d = f"q{frame.d_state}" if frame.d_state is not None else _format_number(frame.d)
        shape = "-"
        if frame.shape is not None:
            shape = f"{frame.shape.kind}({','.join(_format_number(p) for p in frame.shape.params)})"
        nexts = " ".join(str(n) for n in frame.next) or "-"
        lines.append(f"{frame.index}  {frame.geometry or '-'}  {theta}  {d}  "
                     f"{_format_number(frame.a)}  {_format_number(frame.alpha)}  {shape}  {nexts}")
    return "\n".join(lines) + "\n"
