"""Track many inputs at once: one Ray task per video or dataset folder.

Each input (a dataset folder, or a one-camera video with a shared model, rig and initial
state) becomes a :class:`~digiteyes.track_job.TrackJob` whose output folder is
``OUT/<input name>/``; :func:`track_many` runs the jobs as Ray tasks (one CPU each) on a
local Ray started with ``workers`` CPUs or on a cluster at ``address``, and each task
calls :func:`digiteyes.track_job.run_track_job`, the function behind ``digiteyes track``.

* **Progress**: one bar per running input, fed by the rows its task has flushed to
  ``states.csv`` (the driver reads the files; nothing passes through Ray for it).
* **Failures**: a task that raises is recorded with its error's first line; the others go
  on. ``OUT/track-many.json`` lists every input with its status.
* **Reruns**: a task writes ``OUT/<name>/DONE.json`` after everything else; inputs whose
  marker exists are skipped (status ``skipped``). A failed or interrupted input has no
  marker, so the next run does it again.

Ray is an optional dependency (``pip install 'digiteyes[cluster]'``); without it
:func:`track_many` raises :class:`ClusterError` saying so.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

from tqdm import tqdm

from digiteyes.errors import DigitEyesError
from digiteyes.io.safe_paths import distinct_names
from digiteyes.track_job import TrackJob, run_track_job

DONE_MARKER = "DONE.json"
"""Written into an input's output folder after all its other files: the input is done."""

SUMMARY_FILE = "track-many.json"
"""The run's summary in the output folder: one entry per input."""

WORKER_ENV = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
"""Environment of the Ray workers: one thread each, so ``workers`` tasks share the cores
instead of fighting for them."""


class ClusterError(DigitEyesError):
    """Ray is missing or could not be started or reached."""


@dataclass
class InputResult:
    """What became of one input: ``status`` is ``done``, ``skipped`` or ``failed``."""

    input: str
    output: str
    status: str
    frames: int = 0
    lost_frames: int = 0
    seconds: float = 0.0
    cpu_seconds: float = 0.0
    error: str = ""


@dataclass
class TrackManySummary:
    """All inputs of a run, in the order given, and the wall time of the run (s)."""

    results: list[InputResult] = field(default_factory=list)
    wall_seconds: float = 0.0
    workers: int | None = None
    address: str | None = None

    @property
    def failed(self) -> list[InputResult]:
        return [r for r in self.results if r.status == "failed"]

    def to_json(self) -> dict:
        return {"wall_seconds": self.wall_seconds, "workers": self.workers,
                "address": self.address, "inputs": [asdict(r) for r in self.results]}


def is_done(folder: str | Path) -> bool:
    """True when ``folder`` holds the completion marker of a finished input."""
    return (Path(folder) / DONE_MARKER).is_file()


def track_one(job: TrackJob) -> dict:
    """Run one job (the body of a Ray task) and write its completion marker last.

    Returns the marker's content: ``frames``, ``lost_frames``, ``seconds`` (wall time of
    the tracking run) and ``cpu_seconds`` (CPU time of this process meanwhile, all its
    threads). An interrupted run writes no marker and raises KeyboardInterrupt.
    """
    started, cpu_started = time.perf_counter(), time.process_time()
    run = run_track_job(job)
    if run.interrupted:
        raise KeyboardInterrupt
    done = {"inputs": list(job.inputs), "frames": run.n_frames, "lost_frames": run.n_lost,
            "seconds": time.perf_counter() - started,
            "cpu_seconds": time.process_time() - cpu_started}
    marker = Path(job.output) / DONE_MARKER
    partial = marker.with_suffix(".part")
    partial.write_text(json.dumps(done, indent=2) + "\n", encoding="utf-8")
    os.replace(partial, marker)
    return done


def track_in_worker(job: TrackJob) -> dict:
    """:func:`track_one` in a Ray worker, with OpenCV and numba on one thread: a worker
    has one CPU (``num_cpus=1``), and threads beyond it only fight the other workers for
    the cores (:data:`WORKER_ENV` sets the same for libraries that read it at start)."""
    import cv2
    import numba

    cv2.setNumThreads(1)
    numba.set_num_threads(1)
    return track_one(job)


def plan_jobs(inputs: Sequence[str], out_dir: str | Path, template: TrackJob) -> list[TrackJob]:
    """One job per input, output ``out_dir/<name>``
    (:func:`~digiteyes.io.safe_paths.distinct_names`), the other settings from
    ``template``, no progress bar of its own."""
    root = Path(out_dir)
    return [replace(template, inputs=(str(item),), output=str(root / name), progress=False)
            for item, name in zip(inputs, distinct_names(inputs), strict=True)]


def _ray():
    try:
        import ray
    except ImportError:
        raise ClusterError("track-many needs Ray: pip install 'digiteyes[cluster]'") from None
    return ray


def _start_ray(ray, workers: int | None, address: str | None) -> bool:
    """Connect to ``address`` or start a local Ray with ``workers`` CPUs unless Ray is
    already up in this process; returns whether it was started here."""
    if ray.is_initialized():
        return False
    runtime_env = {"env_vars": dict(WORKER_ENV)}
    try:
        if address:
            ray.init(address=address, runtime_env=runtime_env, log_to_driver=False)
        else:
            ray.init(num_cpus=workers or os.cpu_count(), include_dashboard=False,
                     runtime_env=runtime_env, log_to_driver=False)
    except (ConnectionError, RuntimeError, ValueError) as exc:
        where = f"the Ray cluster at {address}" if address else "a local Ray"
        raise ClusterError(f"cannot start {where}: {exc}") from None
    return True


def _frames_written(job: TrackJob) -> int:
    """Rows already flushed to the job's ``states.csv`` (0 before it exists)."""
    try:
        with open(Path(job.output) / "states.csv", "rb") as handle:
            return max(sum(1 for _ in handle) - 1, 0)
    except OSError:
        return 0


def _total_frames(job: TrackJob) -> int | None:
    """Frames the job will track, when the input says (dataset folders), else None."""
    path = Path(job.inputs[0])
    if not path.is_dir():
        return job.max_frames
    try:
        spec = json.loads((path / "sequence.json").read_text(encoding="utf-8"))
        total = int(spec["n_frames"])
    except (OSError, ValueError, KeyError, TypeError):
        return job.max_frames
    return total if job.max_frames is None else min(total, job.max_frames)


def error_line(exc: BaseException) -> str:
    """The first line of what went wrong in a task (Ray wraps the task's exception)."""
    cause = getattr(exc, "cause", None) or exc
    text = str(cause).strip().splitlines()
    return f"{type(cause).__name__}: {text[0] if text else ''}".rstrip(": ")


def track_many(inputs: Sequence[str], out_dir: str | Path, template: TrackJob, *,
               workers: int | None = None, address: str | None = None,
               progress: bool = True, poll_s: float = 0.5,
               echo: Callable[[str], None] | None = None) -> TrackManySummary:
    """Track every input as one Ray task; skip inputs already done; record failures.

    Parameters
    ----------
    inputs : dataset folders or one-camera videos (videos need ``template``'s model, rig
        and initial state).
    out_dir : the output root; input ``k`` goes to ``out_dir/<name k>``.
    template : settings shared by all jobs (``inputs`` and ``output`` are replaced).
    workers : CPUs of the local Ray started here (None: all cores); ignored with
        ``address`` or when Ray is already initialised in this process.
    address : a Ray cluster to connect to (e.g. ``ray://head:10001`` or ``auto``).
    progress : one progress bar per running input (frames tracked).
    echo : called with one line per finished, skipped or failed input.

    Returns the :class:`TrackManySummary`, also written to ``out_dir/track-many.json``.
    Raises :class:`ClusterError` when Ray is missing or cannot be started.
    """
    say = echo or (lambda line: None)
    root = Path(out_dir)
    root.mkdir(parents=True, exist_ok=True)
    jobs = plan_jobs(inputs, root, template)
    summary = TrackManySummary(workers=workers, address=address)
    results: dict[int, InputResult] = {}
    todo = []
    for k, job in enumerate(jobs):
        if is_done(job.output):
            done = json.loads((Path(job.output) / DONE_MARKER).read_text(encoding="utf-8"))
            results[k] = InputResult(job.inputs[0], job.output, "skipped",
                                     done.get("frames", 0), done.get("lost_frames", 0),
                                     done.get("seconds", 0.0), done.get("cpu_seconds", 0.0))
            say(f"skipped {job.inputs[0]} (done before: {job.output})")
        else:
            todo.append(k)
    started = time.perf_counter()
    if todo:
        ray = _ray()
        started_here = _start_ray(ray, workers, address)
        try:
            _run_tasks(ray, jobs, todo, results, progress, poll_s, say)
        finally:
            if started_here:
                ray.shutdown()
    summary.wall_seconds = time.perf_counter() - started
    summary.results = [results[k] for k in range(len(jobs))]
    (root / SUMMARY_FILE).write_text(json.dumps(summary.to_json(), indent=2) + "\n",
                                     encoding="utf-8")
    return summary


def _run_tasks(ray, jobs: list[TrackJob], todo: list[int], results: dict[int, InputResult],
               progress: bool, poll_s: float, say: Callable[[str], None]) -> None:
    remote = ray.remote(num_cpus=1, max_retries=0)(track_in_worker)
    pending = {remote.remote(jobs[k]): k for k in todo}
    bars = {k: tqdm(total=_total_frames(jobs[k]), desc=Path(jobs[k].output).name,
                    unit="frame", position=i, leave=True, disable=not progress)
            for i, k in enumerate(todo)}
    try:
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1, timeout=poll_s)
            for k, bar in bars.items():
                if k not in results:
                    bar.update(_frames_written(jobs[k]) - bar.n)
            for ref in ready:
                k = pending.pop(ref)
                job = jobs[k]
                try:
                    done = ray.get(ref)
                except Exception as exc:  # a failed input is reported; the others go on
                    results[k] = InputResult(job.inputs[0], job.output, "failed",
                                             _frames_written(job), error=error_line(exc))
                    say(f"failed  {job.inputs[0]}: {results[k].error}")
                else:
                    results[k] = InputResult(job.inputs[0], job.output, "done", done["frames"],
                                             done["lost_frames"], done["seconds"],
                                             done["cpu_seconds"])
                    bars[k].update(done["frames"] - bars[k].n)
                    say(f"done    {job.inputs[0]}: {done['frames']} frame(s) in "
                        f"{done['seconds']:.1f} s -> {job.output}")
    except KeyboardInterrupt:
        for ref in pending:
            ray.cancel(ref, force=True)
        raise
    finally:
        for bar in bars.values():
            bar.close()
