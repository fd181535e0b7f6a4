"""Benchmark: the hand's size measured on the first frame at a known start.

Usage::

    python benchmarks/start_size.py [--json FILE] [--seeds N]

For the first frame of six scenarios (``whole-hand``, ``natural``, ``hand-mouse`` and the
``desk``, ``webcam`` and ``egocentric`` camera setups), drawn as our capsule model and as
the independent flesh hand, with hands 0.9, 1.0 and 1.1 times the model's size, one
camera and (where the rig has them) two, and sensor-noise seeds: the size
:func:`digiteyes.trackers.feature_size.start_size` returns, the size of least cost
before its two rules, and how far that cost lies below the cost at the model's size
(:data:`~digiteyes.trackers.feature_size.MIN_GAIN` and
:data:`~digiteyes.trackers.feature_size.DEAD_BAND` were chosen from these figures;
docs/features.md, "The hand's size").
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from digiteyes.benchmarks._machine import machine_info
from digiteyes.camera import Rig
from digiteyes.features.slices import prepare_image
from digiteyes.kinematics.scaling import model_of_size
from digiteyes.synth import RenderOptions, render_views
from digiteyes.synth.scenarios import build_scenario
from digiteyes.synth.setups import setup_scenario
from digiteyes.trackers import FeatureTracker
from digiteyes.trackers.feature_size import (
    START_SCALES,
    feature_evaluation,
    start_size_costs,
)

SIZES = (0.9, 1.0, 1.1)
NOISE_SIGMA = 2.0


def scenarios() -> list[tuple[str, object]]:
    """(name, scenario) of the six first frames."""
    out = [(name, build_scenario(name, n_frames=2))
           for name in ("whole-hand", "natural", "hand-mouse")]
    out += [(name, setup_scenario(name, cameras, n_frames=2))
            for name, cameras in (("desk", 2), ("webcam", 1), ("egocentric", 1))]
    return out


def measure(seeds: int) -> list[dict]:
    """One row per scenario, appearance, size, camera count and seed."""
    one = int(np.argmin(np.abs(START_SCALES - 1.0)))
    rows = []
    for name, scenario in scenarios():
        q = scenario.initial_state
        for size in SIZES:
            hand = model_of_size(scenario.model, size)
            for appearance in ("model", "flesh"):
                for n_cameras in sorted({1, len(scenario.rig)}):
                    rig = Rig(scenario.rig.cameras[:n_cameras])
                    for seed in range(seeds):
                        views = render_views(hand, q, rig, RenderOptions(
                            appearance=appearance, noise_sigma=NOISE_SIGMA), rng=seed)
                        images = [prepare_image(v.image).astype(np.float32) for v in views]
                        tracker = FeatureTracker(scenario.model, rig)
                        evaluate = feature_evaluation(rig, images, q, tracker.options.features,
                                                      tracker.link_names, tracker.tip_names)
                        costs = start_size_costs(scenario.model, evaluate,
                                                 tracker.n_features, None, 5.0)
                        best = int(np.argmin(costs))
                        rows.append({
                            "scenario": name, "appearance": appearance, "size": size,
                            "cameras": n_cameras, "seed": seed,
                            "measured": tracker.start_size_at(images, q),
                            "least_cost_size": float(START_SCALES[best]),
                            "gain_below_size_1": float((costs[one] - costs[best]) / costs[one]),
                        })
    return rows


def summary(rows: list[dict]) -> dict:
    """Per size and appearance: the range of the measured size, of the least-cost size
    and of the gain."""
    out = {}
    for size in SIZES:
        for appearance in ("model", "flesh"):
            sel = [r for r in rows if r["size"] == size and r["appearance"] == appearance]
            out[f"{size} {appearance}"] = {
                key: [min(r[key] for r in sel), max(r[key] for r in sel)]
                for key in ("measured", "least_cost_size", "gain_below_size_1")}
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", default="benchmarks/results/start_size.json")
    parser.add_argument("--seeds", type=int, default=2)
    args = parser.parse_args(argv)
    started = time.perf_counter()
    rows = measure(args.seeds)
    result = {"benchmark": "start_size", "machine": machine_info(), "rows": rows,
              "summary": summary(rows), "wall_seconds": time.perf_counter() - started}
    print(f"{'hand, drawing':<14} {'size returned':>16} {'least-cost size':>16} "
          f"{'cost below size 1':>18}")
    for key, value in result["summary"].items():
        m, b, g = value["measured"], value["least_cost_size"], value["gain_below_size_1"]
        print(f"{key:<14} {m[0]:7.3f}-{m[1]:.3f} {b[0]:10.2f}-{b[1]:.2f} "
              f"{100 * g[0]:11.0f}-{100 * g[1]:.0f} %")
    with open(args.json, "w", encoding="utf-8") as handle:
        json.dump(result, handle, indent=1)
    print(f"{len(rows)} first frames; {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
