"""Where the first run's compile time goes: numba's compile events of the two processes
of a first ``digiteyes demo``, on an empty kernel cache.

Runs two fresh processes, one after the other, with ``NUMBA_CACHE_DIR`` pointing at one
empty temporary folder (the package's own cache is left alone): ``render`` renders frame
0 of a scenario (what the demo's own process compiles before its rendering), then
``track`` runs :func:`digiteyes.warmup.compile_tracking` (the demo's background process;
the renderer's kernels are in the cache by then, as in the demo when the rendering
process compiled them first). Writes ``benchmarks/results/compile_profile.json``: per
process its seconds (wall, CPU, compiling) and per kernel the number of specialisations
compiled (more than one means the callers pass different types), the seconds spent in
its compile events (inclusive, and exclusive of the kernels it compiled on the way) and
the signatures. Usage::

    PYTHONPATH=src python benchmarks/compile_profile.py [SCENARIO]
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

RESULT = Path(__file__).parent / "results" / "compile_profile.json"


class _CompileRecorder:
    """Listener for ``numba:compile`` events: wall seconds per kernel, nested calls
    subtracted for the exclusive figure."""

    def __init__(self) -> None:
        self.stack: list[list] = []
        self.kernels: dict[str, dict] = defaultdict(
            lambda: {"compiles": 0, "inclusive_s": 0.0, "exclusive_s": 0.0, "signatures": []})

    def on_start(self, event) -> None:
        self.stack.append([event.data["dispatcher"], event.data["args"], time.perf_counter(),
                           0.0])

    def on_end(self, event) -> None:
        dispatcher, args, start, nested = self.stack.pop()
        seconds = time.perf_counter() - start
        if self.stack:
            self.stack[-1][3] += seconds
        entry = self.kernels[f"{dispatcher.py_func.__module__}.{dispatcher.py_func.__qualname__}"]
        entry["compiles"] += 1
        entry["inclusive_s"] += seconds
        entry["exclusive_s"] += seconds - nested
        entry["signatures"].append(", ".join(str(a) for a in args))


def _profile(process: str, scenario_name: str) -> dict:
    """Compile events of one of the demo's two processes (run in the child process)."""
    from numba.core import event

    recorder = _CompileRecorder()
    listener = type("L", (event.Listener,), {
        "on_start": lambda self, e: recorder.on_start(e),
        "on_end": lambda self, e: recorder.on_end(e)})()
    event.register("numba:compile", listener)
    from digiteyes.synth import RenderOptions
    from digiteyes.synth.scenarios import build_scenario
    from digiteyes.synth.sequence import render_frames
    from digiteyes.warmup import compile_tracking

    start, cpu_start = time.perf_counter(), time.process_time()
    if process == "render":
        next(render_frames(build_scenario(scenario_name, seed=0, n_frames=1),
                           RenderOptions()))
    else:
        compile_tracking(scenario_name)
    kernels = {name: {**entry, "inclusive_s": round(entry["inclusive_s"], 2),
                      "exclusive_s": round(entry["exclusive_s"], 2)}
               for name, entry in sorted(recorder.kernels.items(),
                                         key=lambda kv: -kv[1]["exclusive_s"])}
    return {"total_s": round(time.perf_counter() - start, 2),
            "cpu_s": round(time.process_time() - cpu_start, 2),
            "compile_s": round(sum(e["exclusive_s"] for e in kernels.values()), 2),
            "kernels": kernels}


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        print(json.dumps(_profile(sys.argv[2], sys.argv[3])))
        return
    scenario = sys.argv[1] if len(sys.argv) > 1 else "whole-hand"
    result: dict = {"scenario": scenario, "processes": {}}
    with tempfile.TemporaryDirectory() as cache:
        for process in ("render", "track"):
            child = subprocess.run(
                [sys.executable, __file__, "--child", process, scenario], check=True,
                capture_output=True, text=True, env={**os.environ, "NUMBA_CACHE_DIR": cache})
            result["processes"][process] = json.loads(child.stdout.strip().splitlines()[-1])
    RESULT.write_text(json.dumps(result, indent=1) + "\n")
    for process, entry in result["processes"].items():
        print(f"{process}: {entry['total_s']} s wall, {entry['cpu_s']} s CPU, "
              f"{entry['compile_s']} s compiling")
        print(f"  {'kernel':<62} {'n':>2} {'excl s':>7} {'incl s':>7}")
        for name, kernel in entry["kernels"].items():
            if kernel["exclusive_s"] >= 0.1 or kernel["compiles"] > 1:
                print(f"  {name:<62} {kernel['compiles']:>2} {kernel['exclusive_s']:>7.2f} "
                      f"{kernel['inclusive_s']:>7.2f}")
    print(f"-> {RESULT}")


if __name__ == "__main__":
    main()
