"""The figure of ``digiteyes bench mouse``'s footage section (docs/mouse3d.md): the pole
of the ``hand-mouse`` flesh render, started automatically and tracked from the images
alone, against the truth. Reads the benchmark's JSON; run from the repository root:

    python benchmarks/mouse_footage_figure.py [--json benchmarks/results/mouse.json]
                                              [--out docs/images/mouse-footage-pole.png]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from digiteyes.apps.mouse3d import write_mouse_pole_plot
from digiteyes.synth.scenarios import MOUSE_PHASES


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", default="benchmarks/results/mouse.json")
    parser.add_argument("--out", default="docs/images/mouse-footage-pole.png")
    args = parser.parse_args()
    footage = json.loads(Path(args.json).read_text()).get("footage")
    rows = [r for r in (footage or {}).get("rows", []) if r.get("appearance") == "flesh"
            and r.get("started")]
    if not rows:
        print(f"{args.json}: no started flesh row in the footage section")
        return 1
    row = rows[0]
    write_mouse_pole_plot(args.out, np.array(row["frame"]), np.array(row["pole_mm"]),
                          np.array(row["true_pole_mm"]),
                          phases=[p for p in MOUSE_PHASES if p[0] < row["frame"][-1]],
                          title="Webcam mouse from the images alone (flesh render): "
                                "estimate solid, truth dashed")
    print(f"-> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
