"""``track-many`` benchmark: throughput of Ray tasks on two workers against the same inputs
tracked one after the other.

The inputs are ``mouse`` scenario datasets (one camera, black cloth, seeds 0, 1, ...)
rendered into a temporary folder with ``digiteyes render``. The reference tracks them one
after the other in this process with :func:`digiteyes.track_many.track_one` (the task's
own function: :func:`digiteyes.track_job.run_track_job` and the completion marker), one
thread for OpenCV and numba, after one untimed one-frame input (imports and kernels
loaded, as the workers' warm-up round below does for them). The contender is
:func:`digiteyes.track_many.track_many` on a local Ray of :data:`WORKERS` CPUs (one
thread per worker). Ray's start-up is timed apart (``ray_start_seconds``), and a warm-up
round (two one-frame inputs) lets every worker import digiteyes and load numba's cached
kernels first, as a long batch does once; ``parallel_seconds_with_warmup`` includes it.
Both sides write the full outputs (state log, overlay video, views, plots, summary).

Keys: ``sequential_seconds``, ``parallel_seconds``, ``speedup`` (sequential / parallel;
the target is at least 1.8 on two workers), ``frames_per_second_*``, ``machine``; CPU
time (less sensitive to a busy machine): ``sequential_cpu_seconds`` (all threads of this
process), ``sequential_cores_used`` (CPU / wall: above 1 when the video encoder's threads
already use the second core, which caps the speedup) and ``parallel_task_cpu_seconds``
(summed over the Ray tasks: more than the sequential figure is per-task overhead).
The machine's load average at the start and end is in ``machine``.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from digiteyes.benchmarks._machine import emit, kernel_threads, machine_info, machine_lines
from digiteyes.synth.scenarios import build_scenario
from digiteyes.synth.sequence import render_scenario
from digiteyes.track_job import TrackJob
from digiteyes.track_many import WORKER_ENV, plan_jobs, track_many, track_one

WORKERS = 2
SPEEDUP_TARGET = 1.8


def render_inputs(folder: Path, count: int, frames: int) -> list[str]:
    """``count`` mouse datasets of ``frames`` frames (seeds 0..count-1) in ``folder``."""
    paths = []
    for seed in range(count):
        path = folder / f"mouse-{seed}"
        render_scenario(build_scenario("mouse", seed=seed, n_frames=frames), path, seed=seed,
                        progress=False)
        paths.append(str(path))
    return paths


def run(json_path: str | None = None, quick: bool = False, *, progress: bool = True) -> dict:
    """Measure both sides; print the table and write ``json_path`` when given."""
    import ray
    count, frames = (2, 10) if quick else (4, 30)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        inputs = render_inputs(root / "inputs", count, frames)
        warm_inputs = render_inputs(root / "warm", WORKERS, 1)
        template = TrackJob((), "", progress=False)
        with kernel_threads(1, 1):
            track_one(plan_jobs(warm_inputs[:1], root / "warm-sequential", template)[0])
        started, cpu_started = time.perf_counter(), time.process_time()
        with kernel_threads(1, 1):
            for job in plan_jobs(inputs, root / "sequential", template):
                track_one(job)
        sequential = time.perf_counter() - started
        sequential_cpu = time.process_time() - cpu_started
        t0 = time.perf_counter()
        ray.init(num_cpus=WORKERS, include_dashboard=False, log_to_driver=False,
                 runtime_env={"env_vars": dict(WORKER_ENV)})
        ray_start = time.perf_counter() - t0
        try:
            t0 = time.perf_counter()
            track_many(warm_inputs, root / "warm-out", template, progress=False)
            warm = time.perf_counter() - t0
            t0 = time.perf_counter()
            summary = track_many(inputs, root / "parallel", template, progress=False)
            parallel = time.perf_counter() - t0
        finally:
            ray.shutdown()
    if summary.failed:
        raise RuntimeError(f"track-many failed: {summary.failed[0].error}")
    total = count * frames
    result = {"machine": machine_info(("ray",)), "inputs": count, "frames_per_input": frames,
              "workers": WORKERS, "sequential_seconds": sequential,
              "parallel_seconds": parallel, "parallel_seconds_with_warmup": parallel + warm,
              "ray_start_seconds": ray_start, "speedup": sequential / parallel,
              "sequential_cpu_seconds": sequential_cpu,
              "parallel_task_cpu_seconds": sum(r.cpu_seconds for r in summary.results),
              "sequential_cores_used": sequential_cpu / sequential,
              "speedup_with_warmup": sequential / (parallel + warm),
              "frames_per_second_sequential": total / sequential,
              "frames_per_second_parallel": total / parallel,
              "target": SPEEDUP_TARGET, "meets_target": sequential / parallel >= SPEEDUP_TARGET,
              "quick": quick}
    return emit(result, format_table(result), json_path)


def format_table(r: dict) -> str:
    lines = [*machine_lines(r["machine"]), "",
             f"track-many: {r['inputs']} mouse datasets x {r['frames_per_input']} frames",
             f"  one after the other (1 thread)   {r['sequential_seconds']:7.1f} s  "
             f"{r['frames_per_second_sequential']:5.1f} frames/s",
             f"  Ray, {r['workers']} workers                  {r['parallel_seconds']:7.1f} s  "
             f"{r['frames_per_second_parallel']:5.1f} frames/s",
             f"  speedup {r['speedup']:.2f}x (target >= {r['target']}x: "
             f"{'met' if r['meets_target'] else 'not met'}); with the workers' warm-up "
             f"{r['speedup_with_warmup']:.2f}x; Ray start {r['ray_start_seconds']:.1f} s",
             f"  CPU time: one after the other {r['sequential_cpu_seconds']:.1f} s "
             f"({r['sequential_cores_used']:.2f} cores busy), Ray tasks "
             f"{r['parallel_task_cpu_seconds']:.1f} s"]
    return "\n".join(lines)
