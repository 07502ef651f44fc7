"""``python -m app.bench triangulation``: the JSON contract and what it must show (interp beats stale, ≤ 1 %)."""

from __future__ import annotations

import json

from app.bench.__main__ import main as bench_main


def test_json_reports_p95_relative_errors_and_interpolation_meets_the_goal(capsys):
    assert bench_main(["triangulation", "--json", "--cases", "150", "--seed", "3"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["cases"] == 150
    assert r["p95_rel_height_interp"] <= 0.01 and r["goal_met"] is True
    assert r["p95_rel_height_no_interp"] > 5 * r["p95_rel_height_interp"]  # 2 m/s, 30°/s, up to 250 ms stale
    assert set(r["by_latency"]) == {"0-50ms", "50-100ms", "100-150ms", "150-200ms", "200-250ms"}
    # Stale poses hurt more the later the frame is processed; interpolation does not care.
    lat = r["by_latency"]
    assert lat["200-250ms"]["no_interp"]["p50_rel_height"] > lat["0-50ms"]["no_interp"]["p50_rel_height"]


def test_text_output_states_the_goal_verdict(capsys):
    assert bench_main(["triangulation", "--cases", "40"]) == 0
    out = capsys.readouterr().out
    assert "goal p95 ≤ 1 % of height with interpolation: MET" in out and "no-interp" in out
