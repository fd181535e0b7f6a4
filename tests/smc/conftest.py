"""Shared fixtures: the first frames of the ``natural`` scenario posed on the cardboard hand."""

import numpy as np
import pytest

from digiteyes import load_model
from digiteyes.synth.scenarios import build_scenario


@pytest.fixture(scope="session")
def natural_cardboard():
    """(model, camera, states (T, n_q)) for 40 frames of ``natural`` on ``cardboard-hand``
    (the scenario's hand states without ``thumb.mp_abd``), one camera."""
    scenario = build_scenario("natural", n_frames=40)
    model = load_model("cardboard-hand")
    states = np.delete(scenario.states, scenario.model.state_index("thumb.mp_abd"), axis=1)
    return model, scenario.rig.cameras[0], states
