"""``digiteyes bench hand-size``: the hand's size measured on the first frame at a known
start (``--quick``: one noise seed, else two).

For the first frame of six scenarios (``whole-hand``, ``natural``, ``hand-mouse`` and the
``desk``, ``webcam`` and ``egocentric`` camera setups), drawn as our capsule model and as
the independent flesh hand, with hands 0.9, 1.0 and 1.1 times the model's size, with the
model's proportions and with every link length off by up to 5 % (a hand that is not the
model scaled; :func:`~digiteyes.synth.perturb.perturb_model`), from the true start and
from starts moved :data:`START_OFFSETS_MM` away, one camera and (where the rig has them)
two, and sensor-noise seeds: the size
:func:`digiteyes.trackers.feature_size.hand_size_at` returns, the size of least cost
before its two rules, how far that cost lies below the cost at the model's size, and
how often the model's size is kept with and without the check of a misplaced start
(:data:`~digiteyes.trackers.feature_size.MIN_GAIN` and
:data:`~digiteyes.trackers.feature_size.DEAD_BAND` were chosen from these figures;
docs/features.md, "The hand's size").
"""

from __future__ import annotations

import time
from itertools import product

import numpy as np

from digiteyes.benchmarks._machine import emit, machine_info, machine_lines
from digiteyes.camera import Rig
from digiteyes.features.slices import prepare_image
from digiteyes.kinematics.scaling import model_of_size
from digiteyes.synth import RenderOptions, render_views
from digiteyes.synth.perturb import perturb_model
from digiteyes.synth.scenarios import build_scenario
from digiteyes.synth.setups import setup_scenario
from digiteyes.trackers import FeatureTracker
from digiteyes.trackers.feature_size import (
    START_SCALES,
    feature_evaluation,
    start_size,
    start_size_costs,
)

SIZES = (0.9, 1.0, 1.1)
NOISE_SIGMA = 2.0
PROPORTIONS = {"model": 0.0, "links 5 %": 0.05}
"""Hand proportions: the model's, or every link length off by up to this fraction (the
perturbation's seed is the noise seed)."""
START_OFFSETS_MM = (0.0, 3.0, 6.0, 10.0)
"""How far the start is moved from the true pose (a random direction per frame); the
hands of the model's proportions only."""


def scenarios() -> list[tuple[str, object]]:
    """(name, scenario) of the six first frames."""
    out = [(name, build_scenario(name, n_frames=2))
           for name in ("whole-hand", "natural", "hand-mouse")]
    out += [(name, setup_scenario(name, cameras, n_frames=2))
            for name, cameras in (("desk", 2), ("webcam", 1), ("egocentric", 1))]
    return out


def measure(seeds: int) -> list[dict]:
    """One row per scenario, size, proportions, appearance, camera count and seed."""
    one = int(np.argmin(np.abs(START_SCALES - 1.0)))
    rows = []
    rng = np.random.default_rng(0)
    for name, scenario in scenarios():
        k = scenario.model.base_state
        for size, (proportions, perturbation), offset, appearance, n_cameras, seed in product(
                SIZES, PROPORTIONS.items(), START_OFFSETS_MM, ("model", "flesh"),
                sorted({1, len(scenario.rig)}), range(seeds)):
            if offset and perturbation:
                continue
            q = np.array(scenario.initial_state, dtype=float)
            direction = rng.standard_normal(3)
            q[k + 4:k + 7] += offset * direction / np.linalg.norm(direction)
            hand = perturb_model(model_of_size(scenario.model, size),
                                 link_length=perturbation, rng=seed)
            rig = Rig(scenario.rig.cameras[:n_cameras])
            views = render_views(hand, scenario.initial_state, rig, RenderOptions(
                appearance=appearance, noise_sigma=NOISE_SIGMA), rng=seed)
            images = [prepare_image(v.image).astype(np.float32) for v in views]
            tracker = FeatureTracker(scenario.model, rig)
            evaluate = feature_evaluation(rig, images, q, tracker.options.features,
                                          tracker.link_names, tracker.tip_names)
            costs = start_size_costs(scenario.model, evaluate, tracker.n_features, None, 5.0)
            best = int(np.argmin(costs))
            rows.append({
                "scenario": name, "appearance": appearance, "size": size,
                "proportions": proportions, "start_offset_mm": offset,
                "cameras": n_cameras, "seed": seed,
                "measured": tracker.start_size_at(images, q),
                "measured_at_start_only": start_size(scenario.model, evaluate,
                                                     tracker.n_features, None, 5.0),
                "least_cost_size": float(START_SCALES[best]),
                "gain_below_size_1": float((costs[one] - costs[best]) / costs[one]),
            })
    return rows


def summary(rows: list[dict]) -> dict:
    """Per size, proportions and appearance: the range of the measured size, of the
    least-cost size and of the gain."""
    out = {}
    for size, proportions, offset, appearance in product(SIZES, PROPORTIONS,
                                                         START_OFFSETS_MM, ("model", "flesh")):
        sel = [r for r in rows if r["size"] == size and r["appearance"] == appearance
               and r["proportions"] == proportions and r["start_offset_mm"] == offset]
        if not sel:
            continue
        label = f"{size} {proportions}" + (f" {offset:g} mm off" if offset else "")
        out[f"{label}, {appearance}"] = {
            key: [min(r[key] for r in sel), max(r[key] for r in sel)]
            for key in ("measured", "least_cost_size", "gain_below_size_1")} | {
            "frames": len(sel),
            "kept_model_size": sum(r["measured"] == 1.0 for r in sel),
            "kept_model_size_at_start_only": sum(r["measured_at_start_only"] == 1.0
                                                 for r in sel)}
    return out


def run(json_path: str | None = None, quick: bool = False) -> dict:
    """Measure every first frame (:func:`measure`); print the table; write JSON to
    ``json_path``."""
    started = time.perf_counter()
    rows = measure(1 if quick else 2)
    result = {"benchmark": "hand-size", "quick": quick, "machine": machine_info(),
              "settings": {"sizes": list(SIZES), "noise_sigma": NOISE_SIGMA,
                           "proportions": PROPORTIONS, "start_offsets_mm": START_OFFSETS_MM,
                           "seeds": 1 if quick else 2},
              "rows": rows, "summary": summary(rows)}
    result["wall_seconds"] = time.perf_counter() - started
    return emit(result, format_table(result), json_path)


def format_table(result: dict) -> str:
    """One line per hand size and drawing: the ranges over the first frames."""
    lines = [f"hand-size benchmark{' (quick)' if result['quick'] else ''}",
             *machine_lines(result["machine"]),
             f"{len(result['rows'])} first frames at the true start (six scenarios, one and "
             f"two cameras)", "",
             f"{'hand, drawing':<30} {'size returned':>16} {'kept 1 (start only)':>20} "
             f"{'least-cost size':>16} {'cost below size 1':>18}"]
    for key, value in result["summary"].items():
        m, b, g = value["measured"], value["least_cost_size"], value["gain_below_size_1"]
        kept = (f"{value['kept_model_size']}/{value['frames']} "
                f"({value['kept_model_size_at_start_only']})")
        lines.append(f"{key:<30} {m[0]:7.3f}-{m[1]:.3f} {kept:>20} "
                     f"{b[0]:10.2f}-{b[1]:.2f} {100 * g[0]:11.0f}-{100 * g[1]:.0f} %")
    return "\n".join(lines)
