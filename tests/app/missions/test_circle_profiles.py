"""The circle on each calibrated simulated autopilot, in virtual time (issue 10's done-when, in process).

The MAVLink path is ``tests/e2e/test_circle_cli.py``; here the same mission and guidance fly the in-process
vehicle with the calibrated airframe and estimator error of each ``--sim-profile``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from app.clock import LoopClock
from app.eventlog import EventLog
from app.flight import fly_mission
from app.missions.table import load_mission
from app.settings import Settings, load_settings
from sim.airframes import SIM_PROFILES
from sim.inproc import InProcessVehicle
from sim.wind import WindConfig

LEAD_ONLY = Path(__file__).resolve().parents[3] / "settings" / "lead-only-guidance.yaml"


async def fly_circle(profile: str, wind: bool, settings: Settings | None = None, seed: int = 1) -> dict:
    p = SIM_PROFILES[profile]
    vehicle = InProcessVehicle(
        seed=seed,
        wind=None if wind else WindConfig.off(),
        profile=p.autopilot,
        vehicle_params=p.airframe,
        estimator=p.estimator,
    )
    flight = await fly_mission(vehicle, load_mission("circle"), settings or Settings(), LoopClock(), EventLog(None))
    assert flight.result.outcome == "completed"
    return flight.figures


@pytest.mark.looptime(noop_cycles=2)
@pytest.mark.parametrize(
    ("profile", "wind", "p95_max_m"),
    [
        ("px4", False, 0.04),  # the thesis's SITL figure
        ("ardupilot", False, 0.04),
        ("px4-sih", False, 0.08),
        ("px4", True, 0.10),
        ("px4-sih", True, 0.10),
        ("ardupilot", True, 0.10),
    ],
)
async def test_circle_tracks_within_the_goal_on_each_calibrated_profile(profile, wind, p95_max_m):
    t = await fly_circle(profile, wind)
    print(f"{profile} {'wind' if wind else 'calm'}: p50 {t['tracking_error_p50_m']:.4f} p95 "
          f"{t['tracking_error_p95_m']:.4f} (h {t['tracking_error_horizontal_p95_m']:.4f}, "
          f"v {t['tracking_error_vertical_p95_m']:.4f}) m")  # fmt: skip
    assert t["tracking_samples"] > 1000
    assert t["tracking_error_p95_m"] <= p95_max_m


@pytest.mark.looptime(noop_cycles=2)
async def test_on_px4_sih_the_compensation_is_what_makes_the_difference():
    """The guidance we started from (a 0.7 s lead only) does not reach the goal on PX4 SIH; real PX4 SIH SITL
    gave that guidance p95 0.22–0.25 m (shared/reference/autopilot-response)."""
    new = await fly_circle("px4-sih", False)
    old = await fly_circle("px4-sih", False, load_settings(LEAD_ONLY))
    old_p95, new_p95 = old["tracking_error_p95_m"], new["tracking_error_p95_m"]
    print(f"px4-sih calm p95: lead only {old_p95:.3f} m, compensated {new_p95:.3f} m")
    assert old["tracking_error_p95_m"] > 0.15
    assert new["tracking_error_p95_m"] < old["tracking_error_p95_m"] / 3.0


def test_app_main_offers_every_simulator_profile():
    from app.main import SIM_PROFILES as APP_PROFILES

    assert set(APP_PROFILES) == set(SIM_PROFILES)
