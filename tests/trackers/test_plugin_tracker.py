"""A second tracker, registered from outside the package, runs through the whole path:
the registry, ``digiteyes track --tracker``, the overlay, ``summary.json``, the state log,
``digiteyes evaluate`` and the benchmark's tracking loop."""

from __future__ import annotations

import json
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pytest

from digiteyes.camera import Rig
from digiteyes.cli import main
from digiteyes.io import VideoReader, open_sequence, read_state_log
from digiteyes.io.track_extras import track_fps
from digiteyes.kinematics import KinematicModel
from digiteyes.kinematics.anatomy import FINGERS
from digiteyes.trackers import (
    TrackerError,
    TrackResult,
    create_tracker,
    register_tracker,
    tracker_names,
)
from digiteyes.viz.overlay import to_rgb
from digiteyes.viz.track_overlay import register_overlay

MARK = (255, 0, 255)


@dataclass(frozen=True)
class HoldStillOptions:
    """The test tracker's one setting: frames after which it calls the track lost."""

    lost_after: int = 1_000_000


@dataclass
class HoldStillDetails:
    """What the test tracker "measured": the mean grey level of each camera's image."""

    mean_level: list[float]


class HoldStillTracker:
    """Reports the initial state in every frame (the "hold still" baseline)."""

    stages = ("measure", "hold")

    def __init__(self, model: KinematicModel, rig: Rig, options: HoldStillOptions) -> None:
        self.model, self.rig, self.options = model, rig, options
        self.state: np.ndarray | None = None
        self.frame = 0

    def reset(self, initial_state: np.ndarray) -> None:
        self.state = np.array(initial_state, dtype=float)
        self.frame = 0

    def step(self, frames: Sequence[np.ndarray]) -> TrackResult:
        start = time.perf_counter()
        self.rig.check_images(frames)
        levels = [float(np.mean(f)) for f in frames]
        measured = time.perf_counter()
        lost = self.frame >= self.options.lost_after
        result = TrackResult(
            state=self.state.copy(), cost=float("nan"), residual_rms_px=float("nan"),
            lost=lost, loss_reason="held too long" if lost else "", iterations=0,
            predicted_state=self.state.copy(), frame_index=self.frame,
            timings={"measure": measured - start, "hold": time.perf_counter() - measured},
            finger_lost={f: lost and f == "index" for f in FINGERS},
            details=HoldStillDetails(levels))
        result.timings["total"] = time.perf_counter() - start
        self.frame += 1
        return result


def draw_hold_still(image, camera_index, camera, result, model):
    """A 6 x 6 mark in the top-left corner: what this tracker draws."""
    out = to_rgb(image).copy()
    out[:6, :6] = MARK
    return out


register_tracker("hold-still", HoldStillTracker, HoldStillOptions,
                 "test baseline: reports the initial state in every frame")
register_overlay(HoldStillDetails, draw_hold_still)


@pytest.fixture(scope="module")
def sequence(tmp_path_factory):
    folder = tmp_path_factory.mktemp("seq") / "whole-hand"
    assert main(["render", "whole-hand", "-o", str(folder), "--frames", "4"]) == 0
    return folder


def test_registry_creates_by_name_and_rejects_unknown_names_and_options(sequence):
    seq = open_sequence(sequence)
    assert tracker_names()[:1] == ("features",) and "hold-still" in tracker_names()
    tracker = create_tracker("hold-still", seq.model, seq.rig, lost_after=2)
    assert isinstance(tracker, HoldStillTracker) and tracker.options.lost_after == 2
    with pytest.raises(TrackerError, match=r"no tracker named 'nope'.*features"):
        create_tracker("nope", seq.model, seq.rig)
    with pytest.raises(TrackerError, match=r"no option 'speed'.*lost_after"):
        create_tracker("hold-still", seq.model, seq.rig, speed=2)
    features = create_tracker("features", seq.model, seq.rig, iterations_per_frame=2,
                              form="quaternion")
    assert features.options.iterations_per_frame == 2 and features.options.form == "quaternion"
    # a value of the wrong type (``--option silhouette_check=maybe`` arrives as a string)
    for key, value, wanted in (("silhouette_check", "maybe", "true or false"),
                               ("colour_foreground", 1, "true or false"),
                               ("iterations_per_frame", 2.5, "an integer"),
                               ("iterations_per_frame", True, "an integer"),
                               ("robust_scale_px", "five", "a number")):
        with pytest.raises(TrackerError, match=f"{key} must be {wanted}, got"):
            create_tracker("features", seq.model, seq.rig, **{key: value})
    relaxed = create_tracker("features", seq.model, seq.rig, robust_scale_px=4,
                             robust_loss=None)
    assert relaxed.options.robust_scale_px == 4 and relaxed.options.robust_loss is None


def test_dotted_options_set_nested_settings(sequence):
    """``digit_search.passes=0`` sets one field of a nested settings object, keeping the
    rest of it and every other option at their defaults; a dotted key that names nothing
    or a plain field, or a bad value, is one clear error."""
    from digiteyes.trackers import DivideConquerOptions
    seq = open_sequence(sequence)
    default = DivideConquerOptions()
    tracker = create_tracker("divide-conquer", seq.model, seq.rig, n_particles=50,
                             **{"digit_search.passes": 0, "palm_search.rounds": 1,
                                "palm_search.samples": 8})
    opts = tracker.options
    assert opts.n_particles == 50 and opts.digit_search.passes == 0
    assert opts.digit_search.palms == default.digit_search.palms
    assert (opts.palm_search.rounds, opts.palm_search.samples) == (1, 8)
    assert opts.palm_search.sigma_deg == default.palm_search.sigma_deg
    assert opts.likelihood == default.likelihood
    with pytest.raises(TrackerError, match=r"no option 'digit_search.pases'; digit_search's "
                                           r"options are .*passes"):
        create_tracker("divide-conquer", seq.model, seq.rig, **{"digit_search.pases": 0})
    with pytest.raises(TrackerError, match=r"option 'n_particles' has no parts"):
        create_tracker("divide-conquer", seq.model, seq.rig, **{"n_particles.x": 0})
    with pytest.raises(TrackerError, match=r"digit_search.palms must be an integer"):
        create_tracker("divide-conquer", seq.model, seq.rig, **{"digit_search.palms": 0.5})
    for order in ({"digit_search": 0, "digit_search.passes": 0},
                  {"digit_search.passes": 0, "digit_search": 0}):
        with pytest.raises(TrackerError, match=r"is set and has parts set too"):
            create_tracker("divide-conquer", seq.model, seq.rig, **order)
    with pytest.raises(TrackerError, match=r"digit_search.steps must be a list"):
        create_tracker("divide-conquer", seq.model, seq.rig, **{"digit_search.steps": "abc"})


def test_track_help_lists_the_registered_trackers(capsys):
    assert main(["track", "--help"]) == 0
    out = " ".join(capsys.readouterr().out.split()).replace("- ", "-")  # unwrap
    assert "hold-still" in out and "features" in out and "test baseline" in out


def test_plugin_runs_through_track_overlay_and_evaluate(sequence, tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["track", str(sequence), "-o", str(out), "--tracker", "hold-still",
                 "--option", "lost_after=2", "--quiet"]) == 0
    seq = open_sequence(sequence)
    log = read_state_log(out / "states.csv", seq.model)
    assert list(log.frames) == [0, 1, 2, 3]
    np.testing.assert_allclose(log.states, np.tile(seq.initial_state, (4, 1)), atol=1e-9)
    assert list(log.lost) == [False, False, True, True]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["tracker"] == "hold-still" and summary["stages"] == ["measure", "hold"]
    assert summary["fps"] == seq.fps and track_fps(out) == seq.fps  # what export reads
    assert summary["lost_frames"] == 2 and summary["first_lost_frame"] == 2
    assert summary["lost_frames_per_finger"] == {"index": 2, "middle": 0, "ring": 0,
                                                 "little": 0}
    assert set(summary["ms_per_frame_by_stage"]) == {"measure", "hold"}
    assert summary["ms_per_iteration"] is None  # no iterations: no per-iteration figure
    with VideoReader(out / "overlay.mp4") as video:
        frames = list(video)
    assert len(frames) == 4
    corner = frames[0][1:5, 1:5].reshape(-1, 3).mean(axis=0)
    assert np.abs(corner - MARK).max() < 40, corner  # the tracker's own drawing (H.264)
    assert "with hold-still" in capsys.readouterr().out

    assert main(["evaluate", str(out), str(sequence)]) == 0
    metrics = json.loads((out / "evaluation" / "metrics.json").read_text())
    assert metrics["run"]["frames"] == 4 and metrics["run"]["lost_frames"] == 2
    tips = metrics["per_frame"]["fingertip_error_mm_per_tip"]
    first = [v[0] for v in tips.values()]
    last = [v[-1] for v in tips.values()]
    assert max(first) < 1e-6 < max(last)  # exact at the start, the hand then moves away


def test_unknown_tracker_is_a_one_line_error(sequence, tmp_path, capsys):
    assert main(["track", str(sequence), "-o", str(tmp_path / "x"), "--tracker", "nope",
                 "--quiet"]) == 2
    assert "nope" in capsys.readouterr().err
    assert main(["track", str(sequence), "-o", str(tmp_path / "y"), "--tracker",
                 "hold-still", "--option", "speed=3", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no option 'speed'" in err[0]


def test_benchmark_loop_takes_any_tracker():
    from digiteyes.benchmarks import tracker as bench
    from digiteyes.synth.scenarios import build_scenario

    sequence = bench.render_sequence(build_scenario("mouse", seed=0, n_frames=3))
    outcome = bench.track_sequence(sequence, HoldStillOptions(), tracker="hold-still")
    assert set(outcome.stage_seconds) == {"measure", "hold"} and outcome.iterations == 0
    np.testing.assert_allclose(outcome.log.states,
                               np.tile(sequence.scenario.initial_state, (3, 1)))


def test_warm_up_step_leaves_the_track_unchanged(sequence, tmp_path):
    from digiteyes.pipeline import run_tracker, step_frames

    seq = open_sequence(sequence)
    cold = [r.state for _, _, r, _ in step_frames(
        create_tracker("features", seq.model, seq.rig, iterations_per_frame=2), iter(seq),
        seq.initial_state)]
    tracker = create_tracker("features", seq.model, seq.rig, iterations_per_frame=2)
    run = run_tracker(tracker, seq.model, seq.rig, iter(seq), seq.initial_state,
                      tmp_path / "warm", overlay=False, views_every=0, progress=False)
    assert run.warm_up_seconds > 0 and run.n_frames == 4
    warm = read_state_log(run.files["states"], seq.model).states
    np.testing.assert_allclose(warm, np.array(cold), atol=1e-9)  # CSV keeps 1e-9 or better
