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
SUITE_OPTIONS = {"trackers": ("accuracy",), "workers": ("accuracy",), "seed": ("accuracy",),
                 "seeds": ("auto-start",)}
"""The options only some suites take: option -> those suites (each passes the option's
value to the suite's ``run`` under the same name)."""


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
    given = {"trackers": None if trackers is None
             else [t.strip() for t in trackers.split(",") if t.strip()],
             "workers": workers, "seed": seed, "seeds": seeds}
    extra = {option: value for option, value in given.items() if value is not None}
    for option in extra:
        if suite not in SUITE_OPTIONS[option]:
            raise click.UsageError(f"--{option} applies to {', '.join(SUITE_OPTIONS[option])}, "
                                   f"not {suite!r}")
    for name in names:
        path = json_path
        if json_path and suite == "all":
            stem, dot, ext = json_path.rpartition(".")
            path = f"{stem}-{name}.{ext}" if dot else f"{json_path}-{name}"
        importlib.import_module(SUITES[name]).run(json_path=path, quick=quick, **extra)
