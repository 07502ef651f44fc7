"""Sea state 3: the vehicle waiting over the object for its final part is met by no crest.

Two scenarios of the evaluation (``sample_scenario(1, i, 3)``, runs 15 and 100) in which, with a crest margin of
0.3 m, the vehicle waiting at the final height (1.03 and 1.25 m over the mean sea, sagging 0.17–0.23 m below it)
was met by a crest 0.82 and 0.97 m high, 0.30 and 0.26 m off the object — off-target touchdowns. Judged from the
simulator's truth (its record of the vehicle at the water), the whole mission flown in virtual time."""

from __future__ import annotations

import pytest

from sim.evaluate_pickup import run_pickup
from sim.pickup_scenarios import sample_scenario


@pytest.mark.parametrize("index", [15, 100])
def test_waiting_for_the_final_part_no_crest_meets_the_vehicle_off_the_object(index):
    scenario = sample_scenario(1, index, 3)
    r = run_pickup(scenario, "seapick", index)
    what = f"{scenario['profile']}, {scenario['object_kind']}"
    print(f"run {index} ({what}): {r['outcome']}, touchdown {r['touchdown_error_m']} m, off-target contacts "
          f"{r['off_target_contacts']}, grabs {r['grabs']}")  # fmt: skip
    assert r["outcome"] == "picked_up" and r["caught"]
    assert r["off_target_touchdowns"] == 0 and r["off_target_contacts"] == 0
