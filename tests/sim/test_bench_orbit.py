"""``sim.bench_orbit``: guidance and the calibrated autopilots following a drifting wave orbit (in virtual time)."""

from __future__ import annotations

import json

import pytest

from sim.bench_orbit import fly_orbit, main


def test_px4_follows_a_drifting_orbit_as_well_as_a_still_one():
    still = fly_orbit("px4", 0.45, 0.0, precise=True)
    drifting = fly_orbit("px4", 0.45, 0.9, precise=True)
    print(still, drifting)
    assert drifting["p95_m"] == pytest.approx(still["p95_m"], abs=0.005)
    assert drifting["p95_m"] <= 0.12


def test_ardupilot_follows_a_sea_state_3_orbit_drifting_at_0_9_mps():
    r = fly_orbit("ardupilot", 0.45, 0.9, precise=True)  # 0.63 m/s around, 1.5 m/s at the most
    print(r)
    assert r["orbit_speed_mps"] == pytest.approx(0.628, abs=0.001)
    assert r["p95_m"] <= 0.06


@pytest.mark.parametrize("precise", [False, True])
def test_ardupilot_follows_a_fast_orbit_drifting_at_0_9_mps_without_a_limit_cycle(precise):
    """1.1 m/s around, 2.0 m/s at the most: with U_a,max 2 m/s (Δ 0.4, precise 0.3) GUIDED's 2.5 m/s² shaping and
    the position loop fell into a ~1 m limit cycle here (p95 1.30 m, precise 1.33); saturating at 1.2 m/s with the
    same gain they do not."""
    r = fly_orbit("ardupilot", 0.79, 0.9, precise=precise)
    print(r)
    assert r["p95_m"] <= 0.08


KNOWN = "a 1.54 m/s orbit drifting at 0.9 m/s still drives GUIDED's shaping and the loop into a ~1 m limit cycle"


@pytest.mark.xfail(strict=True, reason=KNOWN)
def test_ardupilot_follows_a_faster_orbit_drifting_at_0_9_mps():
    r = fly_orbit("ardupilot", 1.1, 0.9, precise=False)
    print(r)
    assert r["p95_m"] <= 0.10


def test_the_json_output_has_one_case_per_combination(capsys):
    assert main(["--profiles", "px4", "--radii", "0.3", "--drifts", "0,0.5", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["period_s"] == 4.5
    cases = out["cases"]
    assert [(c["drift_mps"], c["precise"]) for c in cases] == [(0.0, False), (0.5, False), (0.0, True), (0.5, True)]
    assert all(0.0 < c["p50_m"] <= c["p95_m"] < 0.3 for c in cases)


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["--radii", "0.3,abc"], "'abc' is not a number"),
        (["--drifts", "9"], "9 is outside 0..3 m/s"),
        (["--profiles", "px4,betaflight"], "give distinct names from"),
    ],
)
def test_bad_options_get_one_line_and_status_2(argv, says, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and says in err and len(err.strip().splitlines()) == 1
