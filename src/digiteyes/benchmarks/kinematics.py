"""Kinematics benchmark: forward kinematics and point Jacobians of the 28-state hand.

Measured (DESIGN.md Sec. 7), all on the Appendix A hand:

* ``fk_jac_single_us``: one state, :func:`~digiteyes.kinematics.forward_kinematics` plus
  :func:`~digiteyes.kinematics.point_jacobian` (tangent form) for both ends of every link
  axis and every tip centre (15 * 2 + 5 = 35 points, Jacobian (35, 3, 27)), microseconds;
* ``fk_batch_states_per_s``: forward kinematics of batches of N = 1, 100, 10 000 states,
  states per second;
* the same with pinocchio as a reference, when it is importable (test-only dependency
  ``pin``): ``forwardKinematics`` + ``computeJointJacobians`` + one ``getFrameJacobian``
  (``LOCAL_WORLD_ALIGNED``) per point for one state, and ``framesForwardKinematics`` (all
  joints and the 37 table + 37 shape frames, like ours) in a Python loop over 10 000
  states.
  The pinocchio model is :mod:`digiteyes.benchmarks.pinocchio_hand`.

Every figure is the best of several repeats (``timeit``; the best is the least disturbed
by other processes); the printed table also shows the median. Run it with
``digiteyes bench kinematics [--json FILE]``; docs/kinematics.md explains how to read it.
"""

from __future__ import annotations

import statistics
from collections.abc import Callable

import numpy as np

from digiteyes.benchmarks._machine import emit, machine_info, seconds_per_call
from digiteyes.kinematics import (
    KinematicModel,
    forward_kinematics,
    load_model,
    point_jacobian,
)
from digiteyes.kinematics.rotations import quaternion_from_rotvec

BATCH_SIZES = (1, 100, 10_000)
PINOCCHIO_BATCH = 10_000


def _random_states(model: KinematicModel, rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 28) hand states: random palm pose, joint angles uniform within their limits."""
    lower = np.where(np.isfinite(model.lower), model.lower, -1.0)
    upper = np.where(np.isfinite(model.upper), model.upper, 1.0)
    q = rng.uniform(lower, upper, size=(n, model.n_q))
    q[:, 0:4] = quaternion_from_rotvec(rng.uniform(-np.pi, np.pi, size=(n, 3)))
    q[:, 4:7] = rng.uniform(-200.0, 200.0, size=(n, 3))
    return q


def _hand_points(model: KinematicModel) -> tuple[np.ndarray, np.ndarray]:
    """Both ends of every link axis and every tip centre: rows (P,), offsets (P, 3) mm."""
    rows, offsets = [], []
    for link in model.links:
        if link.kind == "link":
            rows += [link.row, link.row]
            offsets += [(0.0, 0.0, 0.0), (link.length, 0.0, 0.0)]
        elif link.kind == "tip":
            rows.append(link.row)
            offsets.append((0.0, 0.0, 0.0))
    return np.array(rows), np.array(offsets)


def _seconds_per_call(fn: Callable[[], object], repeat: int, min_time: float
                      ) -> tuple[float, float]:
    """(best, median) seconds per call of ``fn`` over ``repeat`` timed runs.

    Each run makes as many calls as needed to last ``min_time`` seconds (at least one).
    """
    runs = seconds_per_call(fn, repeat, min_time)
    return min(runs), statistics.median(runs)


def _time_pinocchio(rows: np.ndarray, offsets: np.ndarray, q_single: np.ndarray,
                    q_batch: np.ndarray, repeat: int, min_time: float
                    ) -> dict[str, tuple[float, float]]:
    """pinocchio timings (best, median seconds per call) of the same work as ours."""
    import pinocchio as pin

    from digiteyes.benchmarks.pinocchio_hand import build_pinocchio_hand

    hand = build_pinocchio_hand(rows, offsets)
    model, data = hand.model, hand.model.createData()
    q_pin = hand.configuration(q_single)
    frame = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    point_ids = hand.point_ids
    # Forward kinematics: the tree without the point frames, so both sides fill the same
    # 37 table frames and 37 shape frames.
    plain = build_pinocchio_hand()
    plain_model, plain_data = plain.model, plain.model.createData()
    batch_pin = plain.configuration(q_batch)

    def fk_jac() -> None:
        pin.forwardKinematics(model, data, q_pin)
        pin.computeJointJacobians(model, data)
        for point in point_ids:
            pin.getFrameJacobian(model, data, point, frame)

    def fk_loop() -> None:
        for q in batch_pin:
            pin.framesForwardKinematics(plain_model, plain_data, q)

    return {
        "fk_jac_single": _seconds_per_call(fk_jac, repeat, min_time),
        "fk_batch": _seconds_per_call(fk_loop, repeat, min_time),
    }


def run(json_path: str | None = None, quick: bool = False) -> dict:
    """Time the hand's kinematics (and pinocchio's), print a table, optionally write JSON.

    Parameters
    ----------
    json_path : write the figures to this JSON file if given.
    quick : fewer repeats and shorter runs (a smoke run; figures are noisier).

    Returns
    -------
    dict
        ``fk_jac_single_us`` (microseconds), ``fk_batch_states_per_s`` (dict keyed by the
        batch size as a string), ``pinocchio_fk_jac_single_us``,
        ``pinocchio_fk_batch_states_per_s`` (dict keyed by ``"10000"``),
        ``ratio_vs_pinocchio`` (digiteyes time / pinocchio time per state for
        ``fk_jac_single`` and ``fk_batch_10000``; above 1 means digiteyes is slower),
        ``median`` (the same figures as medians), ``repeats``, ``n_points`` and
        ``machine``. The pinocchio figures are None when pinocchio is not importable.
    """
    repeat, min_time = (3, 0.02) if quick else (7, 0.2)
    model = load_model("hand")
    rng = np.random.default_rng(0)
    rows, offsets = _hand_points(model)
    q_single = _random_states(model, rng, 1)[0]
    batches = {n: _random_states(model, rng, n) for n in BATCH_SIZES}

    def fk_jac() -> None:
        point_jacobian(forward_kinematics(model, q_single), rows, offsets)

    ours = {"fk_jac_single": _seconds_per_call(fk_jac, repeat, min_time)}
    for n, Q in batches.items():
        ours[f"fk_batch_{n}"] = _seconds_per_call(lambda Q=Q: forward_kinematics(model, Q),
                                                  repeat, min_time)
    try:
        theirs: dict[str, tuple[float, float]] | None = _time_pinocchio(
            rows, offsets, q_single, batches[PINOCCHIO_BATCH], repeat, min_time)
    except ImportError:
        theirs = None

    def figures(pick: int) -> dict[str, object]:
        out: dict[str, object] = {
            "fk_jac_single_us": 1e6 * ours["fk_jac_single"][pick],
            "fk_batch_states_per_s": {str(n): n / ours[f"fk_batch_{n}"][pick]
                                      for n in BATCH_SIZES},
            "pinocchio_fk_jac_single_us": None,
            "pinocchio_fk_batch_states_per_s": None,
            "ratio_vs_pinocchio": None,
        }
        if theirs is not None:
            pin_single = theirs["fk_jac_single"][pick]
            pin_per_state = theirs["fk_batch"][pick] / PINOCCHIO_BATCH
            ours_per_state = ours[f"fk_batch_{PINOCCHIO_BATCH}"][pick] / PINOCCHIO_BATCH
            out["pinocchio_fk_jac_single_us"] = 1e6 * pin_single
            out["pinocchio_fk_batch_states_per_s"] = {str(PINOCCHIO_BATCH): 1.0 / pin_per_state}
            out["ratio_vs_pinocchio"] = {
                "fk_jac_single": ours["fk_jac_single"][pick] / pin_single,
                f"fk_batch_{PINOCCHIO_BATCH}": ours_per_state / pin_per_state,
            }
        return out

    result = {
        "benchmark": "kinematics",
        "model": model.name,
        "n_q": model.n_q,
        "n_v": model.n_v,
        "n_points": len(rows),
        "statistic": "best",
        "repeats": repeat,
        **figures(0),
        "median": figures(1),
        "machine": machine_info(extra=("pinocchio",)),
    }
    return emit(result, format_table(result), json_path)


def format_table(result: dict) -> str:
    """The plain-text report of :func:`run`'s result: machine, then one row per figure."""
    machine = result["machine"]
    median = result["median"]
    have_pin = result["pinocchio_fk_jac_single_us"] is not None
    lines = [
        f"kinematics benchmark: model {result['model']} ({result['n_q']} states, tangent "
        f"size {result['n_v']}), Jacobian of {result['n_points']} points (link-axis ends "
        "and tip centres, tangent form)",
        f"machine: {machine['cpu']}, {machine['cores']} cores, {machine['platform']}",
        f"         Python {machine['python']}, numpy {machine['numpy']}, numba "
        f"{machine['numba']}, pinocchio {machine['pinocchio'] or 'not installed'}",
        f"figures: best of {result['repeats']} repeats (median in brackets)",
        "",
    ]
    if not have_pin:
        lines += ["pinocchio is not importable (test-only dependency 'pin'): reference "
                  "columns are n/a", ""]

    def cell(best: float | None, med: float | None, fmt: str) -> str:
        return "n/a" if best is None else f"{best:{fmt}} ({med:{fmt}})"

    rows = [("measurement", "digiteyes", "pinocchio", "ratio")]
    pin_us = result["pinocchio_fk_jac_single_us"]
    rows.append((
        "FK + Jacobian, 1 state [us]",
        cell(result["fk_jac_single_us"], median["fk_jac_single_us"], ".1f"),
        cell(pin_us, median["pinocchio_fk_jac_single_us"], ".1f"),
        f"{result['ratio_vs_pinocchio']['fk_jac_single']:.2f}" if have_pin else "n/a",
    ))
    for n, rate in result["fk_batch_states_per_s"].items():
        pin_rate = pin_med = ratio = None
        if have_pin and n in result["pinocchio_fk_batch_states_per_s"]:
            pin_rate = result["pinocchio_fk_batch_states_per_s"][n]
            pin_med = median["pinocchio_fk_batch_states_per_s"][n]
            ratio = result["ratio_vs_pinocchio"][f"fk_batch_{n}"]
        rows.append((
            f"FK, batch N={n} [states/s]",
            cell(rate, median["fk_batch_states_per_s"][n], ",.0f"),
            cell(pin_rate, pin_med, ",.0f") + (" loop" if pin_rate is not None else ""),
            "n/a" if ratio is None else f"{ratio:.2f}",
        ))
    widths = [max(len(row[i]) for row in rows) for i in range(4)]
    for i, row in enumerate(rows):
        lines.append("  ".join([row[0].ljust(widths[0]),
                                *(c.rjust(w) for c, w in zip(row[1:], widths[1:], strict=True))]))
        if i == 0:
            lines.append("  ".join("-" * w for w in widths))
    lines += ["",
              "ratio: digiteyes time / pinocchio time per state (above 1: digiteyes is slower).",
              "pinocchio 'loop': framesForwardKinematics called once per state from Python."]
    return "\n".join(lines)
