"""States: validation, the tangent-space retraction, named access and files.

A state is a flat float vector of ``model.n_q`` numbers (28 for the hand). Solvers step in
the tangent space (``model.n_v`` numbers) through :func:`integrate`, like pinocchio's
``integrate`` and Ceres' ``Manifold``: the base rotation step is a 3-vector applied in the
world frame, every other number adds.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Iterable, Iterator
from functools import lru_cache
from pathlib import Path

import numpy as np

from digiteyes.errors import StateError
from digiteyes.jsonfile import read_json_object
from digiteyes.kinematics._kernels import difference_kernel, integrate_kernel
from digiteyes.kinematics.forward import as_state_batch
from digiteyes.kinematics.model import KinematicModel

UNIT_QUATERNION_TOLERANCE = 1e-6


def validate_state(model: KinematicModel, q: np.ndarray, *, normalize: bool = False) -> np.ndarray:
    """Check size, finiteness and the unit quaternion; return a float copy.

    With ``normalize=True`` a non-unit (but non-zero) quaternion is rescaled instead of
    rejected. Raises :class:`StateError` naming what is wrong.
    """
    Q, batched = as_state_batch(model, q)
    Q = Q.copy()
    if model.base_state is not None:
        k = model.base_state
        norms = np.linalg.norm(Q[:, k:k + 4], axis=1)
        if (norms < 1e-12).any():
            raise StateError(f"the base quaternion q{k}..q{k + 3} is zero")
        if normalize:
            Q[:, k:k + 4] /= norms[:, None]
        elif (np.abs(norms - 1.0) > UNIT_QUATERNION_TOLERANCE).any():
            bad = norms[np.argmax(np.abs(norms - 1.0))]
            raise StateError(
                f"the base quaternion q{k}..q{k + 3} must have unit norm, got norm {bad:.9g}"
            )
    return Q if batched else Q[0]


def _state_kernel(kernel, model: KinematicModel, a: np.ndarray, b: np.ndarray,
                  width: int) -> np.ndarray:
    """``kernel(a, b, q_to_v, base_state, out)`` on one pair of rows, or on batches
    broadcast against each other; ``out`` has ``width`` columns (the result's last
    axis)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    base = -1 if model.base_state is None else model.base_state
    if a.ndim == 1 and b.ndim == 1:  # one pair: skip the broadcasting machinery
        out = np.zeros((1, width))
        kernel(np.ascontiguousarray(a).reshape(1, -1), np.ascontiguousarray(b).reshape(1, -1),
               model.q_to_v, base, out)
        return out[0]
    batch = np.broadcast_shapes(a.shape[:-1], b.shape[:-1])
    rows = [np.ascontiguousarray(np.broadcast_to(x, (*batch, x.shape[-1])).reshape(
        -1, x.shape[-1])) for x in (a, b)]
    out = np.zeros((len(rows[0]), width))
    kernel(*rows, model.q_to_v, base, out)
    return out.reshape(*batch, width)


def integrate(model: KinematicModel, q: np.ndarray, dv: np.ndarray) -> np.ndarray:
    """Retraction: the state reached from ``q`` by the tangent step ``dv`` (n_v numbers).

    Base rotation: ``R <- exp([dv_rot]x) R`` (world frame), quaternion renormalised;
    everything else adds. Accepts single states or batches (broadcast against each other).
    """
    return _state_kernel(integrate_kernel, model, q, dv, model.n_q)


def difference(model: KinematicModel, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
    """Tangent step ``dv`` with ``integrate(model, q0, dv) == q1`` (rotation angle <= pi).
    Accepts single states or batches (broadcast against each other)."""
    return _state_kernel(difference_kernel, model, q0, q1, model.n_v)


def resample_states(model: KinematicModel, states: np.ndarray, speed: float) -> np.ndarray:
    """A state sequence (T, n_q) played ``speed`` times faster: the states at times
    ``0, speed, 2 speed, ...`` frames (up to ``T - 1``), each between its two neighbouring
    frames on the state manifold (:func:`difference`, :func:`integrate`: joint angles and
    positions linearly, the base rotation along the great circle). ``speed`` < 1 plays it
    slower. Raises :class:`StateError` for a non-positive speed."""
    if not speed > 0:
        raise StateError(f"speed must be positive, got {speed}")
    states = np.asarray(states, dtype=float)
    last = len(states) - 1
    times = np.arange(int(np.floor(last / speed + 1e-9)) + 1) * speed
    before = np.minimum(np.floor(times + 1e-9).astype(int), last)
    after = np.minimum(before + 1, last)
    step = (times - before)[:, None] * difference(model, states[before], states[after])
    return integrate(model, states[before], step)


def clip_to_limits(model: KinematicModel, q: np.ndarray) -> np.ndarray:
    """Clip joint and translation states into their declared limits."""
    return np.minimum(np.maximum(q, model.lower), model.upper)  # np.clip, without its overhead


def held_at_limits(model: KinematicModel, q: np.ndarray, gradient: np.ndarray) -> np.ndarray:
    """The step columns (n_v,) bool of states that sit at a limit of :func:`clip_to_limits`
    while the descent direction ``-gradient`` (of the cost, per step column) points out of
    it: a step along them would only be clipped back. A projected Gauss-Newton solver holds
    them (the active set of Bertsekas' projected Newton method, docs/solvers.md); the
    others move freely."""
    q = np.asarray(q, dtype=float)
    gradient = np.asarray(gradient, dtype=float)
    held = np.zeros(len(gradient), dtype=bool)
    states, columns, lower, upper = _bounded_states(model)
    at_lower = (q[states] <= lower) & (gradient[columns] > 0.0)
    at_upper = (q[states] >= upper) & (gradient[columns] < 0.0)
    held[columns] = at_lower | at_upper
    return held


@lru_cache(maxsize=64)
def _bounded_states(model: KinematicModel) -> tuple[np.ndarray, ...]:
    """The states with a step column, their columns and their lower and upper limits (a
    solver asks at every iteration)."""
    states = np.flatnonzero(model.q_to_v >= 0)
    return states, model.q_to_v[states], model.lower[states], model.upper[states]


class State:
    """A state vector with names: ``state["index.pip"]``, ``state["q9"]``.

    Wraps a validated copy of ``q``; ``state.q`` is the plain array for the maths.
    """

    def __init__(self, model: KinematicModel, q: np.ndarray | None = None) -> None:
        self.model = model
        q = model.neutral() if q is None else q
        q = np.asarray(q, dtype=float)
        if q.ndim != 1:
            raise StateError(f"State holds one state of size {model.n_q}, got shape {q.shape}")
        self.q = validate_state(model, q)

    def __getitem__(self, name: str) -> float:
        return float(self.q[self._index(name)])

    def __setitem__(self, name: str, value: float) -> None:
        index = self._index(name)
        base = self.model.base_state
        if base is not None and base <= index < base + 4:
            raise StateError(
                f"{name!r} is one number of the base quaternion; set all four at once with "
                "State.set_base_rotation(quat) so the quaternion stays unit"
            )
        value = float(value)
        if not np.isfinite(value):
            raise StateError(f"state {name!r} must be finite, got {value}")
        self.q[index] = value

    def set_base_rotation(self, quat: np.ndarray) -> None:
        """Set the base quaternion (w, x, y, z); it is normalised (must be non-zero)."""
        base = self.model.base_state
        if base is None:
            raise StateError(f"model {self.model.name!r} has no base rotation")
        quat = np.asarray(quat, dtype=float)
        norm = float(np.linalg.norm(quat)) if quat.shape == (4,) else 0.0
        if not (np.isfinite(norm) and norm > 1e-12):
            raise StateError(f"base rotation must be a finite non-zero 4-vector, got {quat}")
        self.q[base:base + 4] = quat / norm

    def _index(self, name: str) -> int:
        try:
            return self.model.state_index(name)
        except KeyError as exc:
            raise StateError(exc.args[0]) from None

    def __iter__(self) -> Iterator[str]:
        return iter(self.model.state_names)

    def to_dict(self) -> dict[str, float]:
        """State names to values (radians, mm, quaternion numbers)."""
        return {name: float(v) for name, v in zip(self.model.state_names, self.q, strict=True)}

    @classmethod
    def from_dict(cls, model: KinematicModel, values: dict[str, float],
                  source: str = "state") -> State:
        """Build from a name -> value mapping that names every state exactly once."""
        missing = [n for n in model.state_names if n not in values]
        extra = [n for n in values if n not in model.state_names]
        if missing or extra:
            parts = []
            if missing:
                parts.append(f"missing {', '.join(missing)}")
            if extra:
                parts.append(f"unknown {', '.join(extra)}")
            raise StateError(f"{source}: does not fit model {model.name!r}: {'; '.join(parts)}")
        try:
            q = np.array([float(values[n]) for n in model.state_names])
        except (TypeError, ValueError) as exc:
            raise StateError(f"{source}: state values must be numbers ({exc})") from None
        try:
            return cls(model, q)
        except StateError as exc:
            raise StateError(f"{source}: {exc}") from None

    def save_json(self, path: str | Path) -> None:
        """Write ``{"model": NAME, "state": {name: value}}`` (full float precision)."""
        payload = {"model": self.model.name, "state": self.to_dict()}
        Path(path).write_text(json.dumps(payload, indent=2) + "\n", encoding="utf-8")

    @classmethod
    def load_json(cls, model: KinematicModel, path: str | Path) -> State:
        """Read a state written by :meth:`save_json` (or a bare name -> value object)."""
        payload = read_json_object(path, StateError, "state file")
        if "state" in payload:
            if payload.get("model", model.name) != model.name:
                raise StateError(
                    f"{path}: state is for model {payload['model']!r}, not {model.name!r}"
                )
            payload = payload["state"]
        if not isinstance(payload, dict):
            raise StateError(f"{path}: 'state' must be an object of name: value")
        return cls.from_dict(model, payload, source=str(path))

    def __repr__(self) -> str:
        return f"State({self.model.name!r}, {np.array2string(self.q, precision=4)})"


def write_states_csv(
    model: KinematicModel,
    path: str | Path,
    states: Iterable[np.ndarray],
    extra: dict[str, Iterable[object]] | None = None,
) -> None:
    """Write states as CSV, one row per state, named columns (``extra`` columns first)."""
    states = np.atleast_2d(np.asarray(list(states), dtype=float))
    extra = {k: list(v) for k, v in (extra or {}).items()}
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow([*extra, *model.state_names])
        for i, q in enumerate(states):
            writer.writerow([*(col[i] for col in extra.values()), *(repr(float(x)) for x in q)])


def read_states_csv(
    model: KinematicModel, path: str | Path
) -> tuple[np.ndarray, dict[str, list[str]]]:
    """Read states written by :func:`write_states_csv`: (N, n_q) array and extra columns."""
    path = Path(path)
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            rows = list(csv.reader(handle))
    except FileNotFoundError:
        raise StateError(f"{path}: no such state file") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise StateError(f"{path}: not a readable state CSV ({exc})") from None
    if not rows:
        raise StateError(f"{path}: empty CSV, expected a header of state names")
    header = rows[0]
    missing = [n for n in model.state_names if n not in header]
    if missing:
        raise StateError(f"{path}: columns for model {model.name!r} missing: {', '.join(missing)}")
    cols = [header.index(n) for n in model.state_names]
    extra_names = [h for h in header if h not in model.state_names]
    extra: dict[str, list[str]] = {h: [] for h in extra_names}
    states = np.empty((len(rows) - 1, model.n_q))
    for i, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise StateError(f"{path}:{i}: expected {len(header)} cells, got {len(row)}")
        try:
            states[i - 2] = [float(row[c]) for c in cols]
        except ValueError as exc:
            raise StateError(f"{path}:{i}: {exc}") from None
        for h in extra_names:
            extra[h].append(row[header.index(h)])
    if len(states):
        validate_state(model, states)
    return states, extra
