"""Sea state 3, ArduCopter: a final descent given up low climbs back before the water meets the vehicle.

Two scenarios of the evaluation (``sample_scenario(1, i, 3)``, runs 8 and 62, both ArduPilot) in which, with the
final part's desired height leading the vehicle by 0.5 m (``descend_max_lead_m``), the vehicle came down at the
envelope's 1 m/s; when it then had to climb back (the object lost from view low down, or drifted past the abort
radius) an ArduCopter accelerating upwards at about 1 m/s² sank on for another 0.4–0.5 m and met the water 0.25
and 0.27 m off the object — off-target touchdowns. With ``final_max_lead_m`` (0.1 m) it comes down at about the
descent speed. Judged from the simulator's truth (its record of the vehicle at the water), the whole mission flown
in virtual time."""

from __future__ import annotations

import pytest

from sim.evaluate_pickup import run_pickup
from sim.pickup_scenarios import sample_scenario


@pytest.mark.parametrize("index", [8, 62])
def test_a_final_descent_given_up_low_does_not_meet_the_water_off_the_object(index):
    scenario = sample_scenario(1, index, 3)
    assert scenario["profile"] == "ardupilot"
    r = run_pickup(scenario, "seapick", index)
    what = f"{scenario['profile']}, {scenario['object_kind']}"
    print(f"run {index} ({what}): {r['outcome']}, touchdown {r['touchdown_error_m']} m, off-target contacts "
          f"{r['off_target_contacts']}, grabs {r['grabs']}")  # fmt: skip
    assert r["outcome"] == "picked_up" and r["caught"]
    assert r["off_target_touchdowns"] == 0 and r["off_target_contacts"] == 0
