"""Sea state 3: scenarios of the evaluation (``sample_scenario(1, i, 3)``) that touched the water off the object,
each for a reason since mended, flown again as a whole mission in virtual time and judged from the simulator's
truth (its record of the vehicle at the water).

- Runs 15 and 100 (PX4), a crest meeting the vehicle waiting for its final part: with a crest margin of 0.3 m the
  vehicle waiting at the final height (1.03 and 1.25 m over the mean sea, sagging 0.17–0.23 m below it) was met
  by a crest 0.82 and 0.97 m high, 0.30 and 0.26 m off the object.
- Runs 8 and 62 (ArduPilot), a final descent given up low: with the final part's desired height leading the
  vehicle by 0.5 m (``descend_max_lead_m``) it came down at the envelope's 1 m/s; when it then had to climb back
  (the object lost from view low down) an ArduCopter, accelerating upwards at about 1 m/s², sank on and met the
  water 0.25 and 0.28 m off the object. With ``final_max_lead_m`` (0.1 m) it comes down at about the descent
  speed."""

from __future__ import annotations

import pytest

from sim.evaluate_pickup import run_pickup
from sim.pickup_scenarios import sample_scenario


@pytest.mark.parametrize(
    "index", [pytest.param(15, id="crest-15"), pytest.param(100, id="crest-100"),
              pytest.param(8, id="given-up-low-8"), pytest.param(62, id="given-up-low-62")],
)  # fmt: skip
def test_the_vehicle_meets_the_water_only_over_the_object(index):
    scenario = sample_scenario(1, index, 3)
    r = run_pickup(scenario, "seapick", index)
    what = f"{scenario['profile']}, {scenario['object_kind']}"
    print(f"run {index} ({what}): {r['outcome']}, touchdown {r['touchdown_error_m']} m, off-target contacts "
          f"{r['off_target_contacts']}, grabs {r['grabs']}")  # fmt: skip
    assert r["outcome"] == "picked_up" and r["caught"]
    assert r["off_target_touchdowns"] == 0 and r["off_target_contacts"] == 0
