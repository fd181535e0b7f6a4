"""A hand that slides out of the image is flagged lost, never a crash (tracker issue)."""

from __future__ import annotations

import numpy as np

from digiteyes.camera import Rig
from digiteyes.synth import RenderOptions, render_views
from digiteyes.synth.scenarios import build_scenario
from digiteyes.trackers import FeatureTracker


def test_hand_sliding_out_of_view_is_flagged_lost_and_tracking_goes_on() -> None:
    scenario = build_scenario("whole-hand", n_frames=2)
    rig = Rig((scenario.rig[0],))
    start = scenario.states[0]
    states = np.repeat(start[None], 16, axis=0)
    states[:, 4] += np.linspace(0.0, 600.0, 16)  # 40 mm per frame along the table, 600 mm
    tracker = FeatureTracker(scenario.model, rig)
    tracker.reset(start)
    results = []
    for q in states:
        image = render_views(scenario.model, q, rig, RenderOptions(), rng=0)[0].image
        results.append(tracker.step([image]))
    assert not results[0].lost
    assert results[-1].lost and results[-1].loss_reason
    assert results[-1].details.n_valid_links + results[-1].details.n_valid_tips \
            < results[0].details.n_valid_links
    assert all(np.isfinite(r.state).all() for r in results)
    assert np.isclose(np.linalg.norm(results[-1].state[:4]), 1.0)
