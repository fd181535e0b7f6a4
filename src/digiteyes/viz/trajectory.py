"""The trajectory plots of a run (thesis Figs. 4.7, 4.8), one writer and one set of file
names for ``digiteyes track`` and the evaluation report:

* ``trajectory-palm.png``: palm rotation (quaternion) and translation over time;
* ``trajectory-joints.png``: the joint angles of the index finger and the thumb (the first
  two digits of models without them).

With the truth the true curves are drawn dashed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from digiteyes.kinematics import KinematicModel
from digiteyes.kinematics.anatomy import finger_of, joint_angle_states, palm_pose
from digiteyes.viz.plots import plot_joint_angles, plot_palm_trajectory, save_figure

PALM_PLOT = "trajectory-palm"
JOINTS_PLOT = "trajectory-joints"
PLOTTED_DIGITS = ("index", "thumb")


def write_trajectory_plots(model: KinematicModel, states: np.ndarray, out: str | Path, *,
                           truth: np.ndarray | None = None, t: np.ndarray | None = None,
                           xlabel: str = "frame") -> dict[str, Path]:
    """Write the palm and joint-angle plots of ``states`` (T, n_q) into ``out``.

    Parameters
    ----------
    model : the kinematic model of the states.
    states : estimated states, one row per frame.
    out : folder to write into (must exist).
    truth : (T, n_q) true states of the same frames, drawn dashed; None for none.
    t : (T,) time axis (default: 0, 1, ... frames).
    xlabel : label of the time axis.

    Returns
    -------
    dict
        :data:`PALM_PLOT` and :data:`JOINTS_PLOT` -> the PNG written (a plot the model
        has nothing for, e.g. no palm, is left out).
    """
    out = Path(out)
    states = np.asarray(states, dtype=float)
    t = np.arange(len(states), dtype=float) if t is None else np.asarray(t, dtype=float)
    files: dict[str, Path] = {}
    pose = palm_pose(model, states)
    true_pose = None if truth is None else palm_pose(model, truth)
    if pose is not None:
        fig = plot_palm_trajectory(t, pose[0], None if true_pose is None else true_pose[0],
                                   pose[1], None if true_pose is None else true_pose[1],
                                   xlabel=xlabel)
        files[PALM_PLOT] = save_figure(fig, out / f"{PALM_PLOT}.png")
    idx = joint_angle_states(model)
    by_digit: dict[str, list[str]] = {}
    for i in idx:
        by_digit.setdefault(finger_of(model.state_names[i]), []).append(model.state_names[i])
    chosen = [d for d in PLOTTED_DIGITS if d in by_digit] or list(by_digit)[:2]
    if chosen:
        est_deg = {model.state_names[i]: np.degrees(states[:, i]) for i in idx}
        true_deg = None if truth is None else \
            {model.state_names[i]: np.degrees(truth[:, i]) for i in idx}
        fig = plot_joint_angles(t, {d: by_digit[d] for d in chosen}, est_deg, true_deg,
                                xlabel=xlabel,
                                title=f"Joint angles of {' and '.join(chosen)}")
        files[JOINTS_PLOT] = save_figure(fig, out / f"{JOINTS_PLOT}.png")
    return files
