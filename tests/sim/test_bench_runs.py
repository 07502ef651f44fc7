"""The run-cost benchmark's figures and its check that results stay identical (``sim.bench_runs``)."""

from __future__ import annotations

from sim.bench_runs import cost_summary, differences


def test_cost_summary_gives_per_run_medians_and_speedups_against_real_time():
    """Medians per run, and mission time over wall time for the median run and for all runs together."""
    s = cost_summary(mission_s=[100.0, 200.0, 300.0], wall_s=[1.0, 4.0, 3.0], cpu_s=[0.9, 3.5, 2.8])
    assert s["runs"] == 3
    assert s["wall_s_median"] == 3.0
    assert s["cpu_s_median"] == 2.8
    assert s["speedup_median"] == 100.0  # 100x, 50x, 100x
    assert s["speedup_total"] == 75.0  # 600 s of mission in 8 s


def test_differences_names_each_run_and_field_that_changed():
    """A result that differs in any field — a float's last digit included — is named with its fields."""
    ref = [{"config": "seapick", "run": 0, "outcome": "picked_up", "touchdown_error_m": 0.1234}]
    same = [dict(ref[0])]
    changed = [dict(ref[0], touchdown_error_m=0.1235, outcome="failed")]
    assert differences(ref, same) == []
    assert differences(ref, changed) == ["seapick run 0: outcome, touchdown_error_m"]
    assert differences(ref, []) == ["0 results against 1"]
