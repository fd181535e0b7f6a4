"""``digiteyes bench NAME``: speed and accuracy benchmarks (table + JSON)."""

from __future__ import annotations

import importlib

import click

SUITES = {
    "kinematics": "digiteyes.benchmarks.kinematics",
    "render": "digiteyes.benchmarks.render",
    "smoothing": "digiteyes.benchmarks.smoothing",
    "tracker": "digiteyes.benchmarks.tracker",
    "smc": "digiteyes.benchmarks.smc",
    "templates": "digiteyes.benchmarks.templates",
    "mouse": "digiteyes.benchmarks.mouse",
    "track-many": "digiteyes.benchmarks.track_many",
    "accuracy": "digiteyes.benchmarks.accuracy",
    "auto-start": "digiteyes.benchmarks.auto_start",
    "hand-size": "digiteyes.benchmarks.hand_size",
    "clutter-flag": "digiteyes.benchmarks.clutter_flag",
    "render-variants": "digiteyes.benchmarks.render_variants",
}
TRACKER_SUITES = ("accuracy",)
"""Suites that take ``--trackers``, ``--workers`` and ``--seed``."""


@click.command()
@click.argument("suite", type=click.Choice([*SUITES, "all"]))
@click.option("--json", "json_path", type=click.Path(dir_okay=False),
              help="Write the figures to this JSON file (with 'all': one file per suite, "
                   "suffixed by the suite name).")
@click.option("--quick", is_flag=True, help="Fewer repeats and frames (for a smoke run).")
@click.option("--trackers", help="Comma-separated registered tracker names (suite "
                                 "'accuracy'; default: every registered tracker).")
@click.option("--workers", type=click.IntRange(min=1),
              help="Worker processes that render and track (suite 'accuracy'; default 2, "
                   "1 with --quick).")
@click.option("--seed", type=click.IntRange(min=0),
              help="Seed of the scenarios' motions and sensor noise (suite 'accuracy'; "
                   "default 0, the committed table's).")
@click.option("--seeds", type=click.IntRange(min=2),
              help="Number of scenario seeds (suite 'auto-start'; default 3).")
def bench(suite: str, json_path: str | None, quick: bool, trackers: str | None,
          workers: int | None, seed: int | None, seeds: int | None) -> None:
    """Run benchmark SUITE (one of the names above) or all."""
    names = list(SUITES) if suite == "all" else [suite]
    extra: dict = {}
    for flag, value in (("--trackers", trackers), ("--workers", workers), ("--seed", seed)):
        if value is not None and suite not in TRACKER_SUITES:
            raise click.UsageError(f"{flag} applies to {', '.join(TRACKER_SUITES)}, "
                                   f"not {suite!r}")
    if seeds is not None:
        if suite != "auto-start":
            raise click.UsageError(f"--seeds applies to auto-start, not {suite!r}")
        extra["seeds"] = seeds
    if trackers is not None:
        extra["trackers"] = [t.strip() for t in trackers.split(",") if t.strip()]
    if workers is not None:
        extra["workers"] = workers
    if seed is not None:
        extra["seed"] = seed
    for name in names:
        path = json_path
        if json_path and suite == "all":
            stem, dot, ext = json_path.rpartition(".")
            path = f"{stem}-{name}.{ext}" if dot else f"{json_path}-{name}"
        importlib.import_module(SUITES[name]).run(json_path=path, quick=quick, **extra)
