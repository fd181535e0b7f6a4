"""``digiteyes prior fit`` on a small made-up recording, and the configuration-space plot."""

import numpy as np

from digiteyes import load_model
from digiteyes.cli import main
from digiteyes.smc.configuration import ConfigurationSpace
from digiteyes.smc.prior import default_configuration_space
from digiteyes.viz.configuration_space import plot_configuration_track
from digiteyes.viz.plots import save_figure


def test_prior_fit_command(tmp_path, capsys):
    rng = np.random.default_rng(0)
    curl = rng.uniform(0, 1, (500, 1))
    glove = np.zeros((500, 23))
    glove[:, 4:20] = -curl * rng.uniform(0.5, 1.2, 16)          # flexion (glove: negative)
    glove += rng.normal(0, 0.01, glove.shape)
    data = tmp_path / "rec.csv"
    np.savetxt(data, glove, delimiter=",")
    out = tmp_path / "prior.npz"
    assert main(["prior", "fit", str(data), "-o", str(out), "--dims", "3"]) == 0
    text = capsys.readouterr().out
    assert "kept 3 dimensions" in text and "500 samples" in text
    space = ConfigurationSpace.load(out)
    assert space.n_dims == 3 and space.kept_variance()[0] > 0.8       # one synergy
    assert main(["prior", "fit", str(tmp_path / "missing.csv"), "-o", str(out)]) == 2
    assert "missing.csv" in capsys.readouterr().err


def test_configuration_plot_writes_png(tmp_path):
    space = default_configuration_space(load_model("cardboard-hand"))
    track = np.linspace(space.basis[0], space.basis[5], 30)
    fig = plot_configuration_track(space, track, track + 0.01, particles=track[:5])
    path = save_figure(fig, tmp_path / "space.png")
    assert path.stat().st_size > 10_000
