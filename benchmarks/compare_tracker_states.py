"""Check that a change left the feature tracker's behaviour alone (issue 11's acceptance).

``record OUT.npz`` tracks the whole-hand scenario (60 frames, seed 0, the benchmark's
rendering: grey, sensor noise 2) with the default options, in stereo and with camera 0
alone, and saves the states and residual RMS per frame. ``compare A.npz B.npz`` prints,
per array, whether two recordings are identical or their largest difference. Run
``record`` on the commit before a change and on the change, then ``compare``.
"""

from __future__ import annotations

import sys

import numpy as np

from digiteyes.benchmarks.tracker import render_sequence, track_sequence
from digiteyes.synth.scenarios import build_scenario
from digiteyes.trackers import FeatureTrackerOptions

FRAMES = 60


def record(path: str) -> None:
    """Track whole-hand stereo and mono; save states and residual RMS to ``path``."""
    scenario = build_scenario("whole-hand", seed=0, n_frames=FRAMES)
    sequence = render_sequence(scenario)
    arrays = {}
    for name, cameras in (("stereo", None), ("mono", (0,))):
        outcome = track_sequence(sequence.cameras(cameras), FeatureTrackerOptions())
        arrays[name] = outcome.log.states
        arrays[f"{name}_rms"] = outcome.log.residual_rms_px
    np.savez(path, **arrays)
    print(f"saved {path}")


def compare(a_path: str, b_path: str) -> None:
    """Print, per array, identical or the largest absolute difference."""
    a, b = np.load(a_path), np.load(b_path)
    for key in a.files:
        if np.array_equal(a[key], b[key], equal_nan=True):
            print(f"{key:<12} {a[key].shape} identical")
        else:
            print(f"{key:<12} {a[key].shape} max |difference| "
                  f"{np.nanmax(np.abs(a[key] - b[key])):.3g}")


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "record":
        record(sys.argv[2])
    elif len(sys.argv) == 4 and sys.argv[1] == "compare":
        compare(sys.argv[2], sys.argv[3])
    else:
        sys.exit("usage: compare_tracker_states.py record OUT.npz | compare A.npz B.npz")
