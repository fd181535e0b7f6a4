"""``digiteyes bench hand-size`` on a subset: the rows it reports agree with the trackers."""

from __future__ import annotations

import json

import pytest

from digiteyes.benchmarks import hand_size
from digiteyes.cli import main


@pytest.fixture(scope="module")
def rows(monkeypatch_module):
    monkeypatch_module.setattr(hand_size, "SIZES", (0.9, 1.0))
    scenarios = hand_size.scenarios
    monkeypatch_module.setattr(hand_size, "scenarios", lambda: scenarios()[:1])
    return hand_size.measure(1)


@pytest.fixture(scope="module")
def monkeypatch_module():
    with pytest.MonkeyPatch.context() as patch:
        yield patch


def test_rows_measure_the_rendered_size(rows):
    assert {(r["size"], r["proportions"], r["appearance"], r["cameras"]) for r in rows} == {
        (s, p, a, c) for s in (0.9, 1.0) for p in hand_size.PROPORTIONS
        for a in ("model", "flesh") for c in (1, 2)}
    for row in rows:
        if row["start_offset_mm"]:  # a misplaced start never rescales the model's size
            assert row["size"] != 1.0 or row["measured"] == 1.0, row
            continue
        assert row["measured"] == pytest.approx(row["size"], abs=0.04), row
        assert abs(row["least_cost_size"] - row["size"]) <= 0.06, row
        if row["size"] == 0.9:
            assert row["gain_below_size_1"] > 0.25, row
    summary = hand_size.summary(rows)
    assert summary["0.9 model, model"]["measured"][0] == min(
        r["measured"] for r in rows if r["size"] == 0.9 and r["appearance"] == "model"
        and r["proportions"] == "model" and not r["start_offset_mm"])


def test_the_command_writes_its_table_and_json(rows, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(hand_size, "measure", lambda seeds: rows)
    path = tmp_path / "hand_size.json"
    assert main(["bench", "hand-size", "--quick", "--json", str(path)]) == 0
    result = json.loads(path.read_text())
    assert result["benchmark"] == "hand-size" and len(result["rows"]) == len(rows)
    assert "0.9 links 5 %, flesh" in capsys.readouterr().out
