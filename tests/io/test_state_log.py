"""State logs: exact round trip, a row flushed per append, interrupted files, wrong model."""

from __future__ import annotations

import numpy as np
import pytest

from digiteyes.errors import DatasetError
from digiteyes.io import StateLogWriter, read_state_log
from digiteyes.kinematics import load_model


def random_states(model, rng, n):
    q = np.tile(model.neutral(), (n, 1))
    q[:, 7:] = rng.uniform(-1, 1, (n, model.n_q - 7))
    quat = rng.normal(size=(n, 4))
    q[:, :4] = quat / np.linalg.norm(quat, axis=1, keepdims=True)
    q[:, 4:7] = rng.uniform(-300, 300, (n, 3))
    return q


def test_round_trip_is_exact(tmp_path, hand):
    rng = np.random.default_rng(0)
    states = random_states(hand, rng, 5)
    residual = [0.5, np.nan, 1.25, 3.0, 0.1]
    with StateLogWriter(tmp_path / "run" / "states.csv", hand) as log:
        for i, q in enumerate(states):
            log.append(10 + i, q, time_s=0.01 * i, lost=i == 3, residual_rms_px=residual[i],
                       iterations=i + 1)
    header = (tmp_path / "run" / "states.csv").read_text().splitlines()[0].split(",")
    assert header[:5] == ["frame", "time_s", "lost", "residual_rms_px", "iterations"]
    assert tuple(header[5:]) == hand.state_names
    read = read_state_log(tmp_path / "run" / "states.csv", hand)
    assert len(read) == 5
    np.testing.assert_array_equal(read.frames, np.arange(10, 15))
    np.testing.assert_array_equal(read.states, states)
    np.testing.assert_array_equal(read.lost, [False, False, False, True, False])
    np.testing.assert_array_equal(read.residual_rms_px, residual)
    np.testing.assert_array_equal(read.iterations, [1, 2, 3, 4, 5])
    np.testing.assert_array_equal(read.time_s, 0.01 * np.arange(5))


def test_each_row_is_flushed(tmp_path, hand):
    path = tmp_path / "states.csv"
    writer = StateLogWriter(path, hand)
    for i in range(3):
        writer.append(i, hand.neutral(), time_s=0.0, lost=False, residual_rms_px=1.0,
                      iterations=2)
        assert len(read_state_log(path, hand)) == i + 1  # readable while the writer is open
    writer.close()


def test_row_cut_short_by_an_interruption_is_dropped(tmp_path, hand):
    path = tmp_path / "states.csv"
    with StateLogWriter(path, hand) as log:
        for i in range(2):
            log.append(i, hand.neutral(), time_s=0.0, lost=False, residual_rms_px=1.0,
                       iterations=2)
    path.write_text(path.read_text() + "2,0.0,0,1.0,2,1.0,0.0")
    assert len(read_state_log(path, hand)) == 2


def test_log_of_another_model_is_refused(tmp_path, hand):
    mouse = load_model("mouse-hand")
    path = tmp_path / "states.csv"
    with StateLogWriter(path, mouse) as log:
        log.append(0, mouse.neutral(), time_s=0.0, lost=False, residual_rms_px=1.0,
                   iterations=1)
    with pytest.raises(DatasetError, match=r"not a log of model 'hand'.*palm\.qw"):
        read_state_log(path, hand)


def test_bad_cells_name_file_and_line(tmp_path, hand):
    path = tmp_path / "states.csv"
    with StateLogWriter(path, hand) as log:
        for i in range(2):
            log.append(i, hand.neutral(), time_s=0.0, lost=False, residual_rms_px=1.0,
                       iterations=2)
    lines = path.read_text().splitlines()
    lines[2] = "one" + lines[2][1:]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(DatasetError, match=r"states\.csv:3: column 'frame'"):
        read_state_log(path, hand)
    with pytest.raises(DatasetError, match="no such state log"):
        read_state_log(tmp_path / "absent.csv", hand)


def test_append_checks_state_size(tmp_path, hand):
    from digiteyes.errors import StateError

    with StateLogWriter(tmp_path / "s.csv", hand) as log, pytest.raises(StateError, match="28"):
        log.append(0, np.zeros(5), time_s=0, lost=False, residual_rms_px=0, iterations=0)


def test_the_hand_scale_column_round_trips_and_defaults_to_one(tmp_path, hand):
    """A tracker that fits the hand's size writes ``hand_scale`` (after ``reinitialised``);
    a log without the column reads as scale 1; a scale that is not positive is refused
    with the file and line."""
    states = random_states(hand, np.random.default_rng(1), 3)
    path = tmp_path / "states.csv"
    with StateLogWriter(path, hand, reinitialised=True, hand_scale=True) as log:
        for i, q in enumerate(states):
            log.append(i, q, time_s=0.0, lost=False, residual_rms_px=1.0, iterations=1,
                       reinitialised=i == 1, hand_scale=0.9 + 0.01 * i)
    header = path.read_text().splitlines()[0].split(",")
    assert header[5:7] == ["reinitialised", "hand_scale"]
    read = read_state_log(path, hand)
    np.testing.assert_array_equal(read.hand_scale, [0.9, 0.91, 0.92])
    np.testing.assert_array_equal(read.states, states)
    with StateLogWriter(tmp_path / "plain.csv", hand) as log:
        log.append(0, states[0], time_s=0.0, lost=False, residual_rms_px=1.0, iterations=1)
    np.testing.assert_array_equal(read_state_log(tmp_path / "plain.csv", hand).hand_scale, [1.0])
    lines = path.read_text().splitlines()
    cells = lines[2].split(",")
    cells[6] = "-0.5"
    lines[2] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(DatasetError, match=r"states.csv:3: column 'hand_scale' must be positive"):
        read_state_log(path, hand)
