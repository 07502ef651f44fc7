"""The circle on each calibrated simulated autopilot, in virtual time (issue 10's done-when, in process).

The MAVLink path is ``tests/e2e/test_circle_cli.py``; here the same mission and guidance fly the in-process
vehicle with the calibrated airframe and estimator error of each ``--sim-profile``.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pytest

from app.clock import LoopClock
from app.eventlog import EventLog
from app.flight import fly_mission
from app.missions.circle import CircleTarget
from app.missions.table import load_mission
from app.settings import Settings, load_settings
from sim.airframes import SIM_PROFILES
from sim.inproc import InProcessVehicle
from sim.wind import WindConfig

LEAD_ONLY = Path(__file__).resolve().parents[3] / "settings" / "lead-only-guidance.yaml"


async def fly_circle(
    profile: str, wind: bool, settings: Settings | None = None, seed: int = 1, circle: dict | None = None
) -> dict:
    p = SIM_PROFILES[profile]
    vehicle = InProcessVehicle(
        seed=seed,
        wind=None if wind else WindConfig.off(),
        profile=p.autopilot,
        vehicle_params=p.airframe,
        estimator=p.estimator,
    )
    table = load_mission("circle")
    if circle:
        table = table.model_copy(update={"params": table.params.model_copy(update=circle)})
    flight = await fly_mission(vehicle, table, settings or Settings(), LoopClock(), EventLog(None))
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


# a floating object's wave orbit at sea state 2: 0.3 m radius, one turn in 3 s (0.63 m/s, 1.3 m/s²)
WAVE_ORBIT = {"circle_radius_m": 0.3, "circle_v_reduction_s": 3.0 / (2.0 * math.pi), "circle_laps": 12}


def ask_for_precision(monkeypatch: pytest.MonkeyPatch) -> None:
    """The circle's target asks guidance for precision, as the pickup's does going down onto the object."""
    plain = CircleTarget.target_at
    monkeypatch.setattr(CircleTarget, "target_at", lambda self, t_s: replace(plain(self, t_s), precise=True))


@pytest.mark.looptime(noop_cycles=2)
@pytest.mark.parametrize(("profile", "p95_max_m"), [("px4", 0.12), ("px4-sih", 0.16)])
async def test_px4_follows_a_precise_target_on_a_wave_orbit_closer(profile, p95_max_m, monkeypatch):
    """PX4's velocity loop lags a 3 s orbit by more than the lead can make up; the position loop closes the rest,
    and its error scales with Δ. A target that asks for precision (the pickup going down onto the object) gets
    PX4's precise Δ (0.25 m, against 0.4): the pickup's touchdown error came mostly from this lag."""
    loose = await fly_circle(profile, True, circle=WAVE_ORBIT)
    ask_for_precision(monkeypatch)
    tight = await fly_circle(profile, True, circle=WAVE_ORBIT)
    print(f"{profile} wave orbit p95: {loose['tracking_error_p95_m']:.3f} m, precise "
          f"{tight['tracking_error_p95_m']:.3f} m")  # fmt: skip
    assert tight["tracking_samples"] > 1000
    assert tight["tracking_error_p95_m"] <= p95_max_m < loose["tracking_error_p95_m"]


@pytest.mark.looptime(noop_cycles=2)
async def test_ardupilot_follows_a_precise_target_closer_and_its_circle_does_not_ring(monkeypatch):
    """GUIDED closes a position loop of its own under ours, so ArduPilot's precise gain is milder than PX4's
    (U_a,max/Δ 6.7 1/s against 5; PX4 8): at 8 1/s the 4 m circle rang (p95 0.23 m calm, 0.20 m in wind, against
    0.016 and 0.046). At 6.7 the wave orbit is followed closer, and the 4 m circle made precise flies as well as
    the plain one."""
    loose = await fly_circle("ardupilot", True, circle=WAVE_ORBIT)
    ask_for_precision(monkeypatch)
    tight = await fly_circle("ardupilot", True, circle=WAVE_ORBIT)
    calm = await fly_circle("ardupilot", False)
    wind = await fly_circle("ardupilot", True)
    print(f"ardupilot wave orbit p95: {loose['tracking_error_p95_m']:.4f} m, precise "
          f"{tight['tracking_error_p95_m']:.4f} m; 4 m circle precise: calm {calm['tracking_error_p95_m']:.4f}, "
          f"wind {wind['tracking_error_p95_m']:.4f} m")  # fmt: skip
    assert tight["tracking_error_p95_m"] <= 0.05 < loose["tracking_error_p95_m"]
    # the goals of the plain circle (test_circle_tracks_within_the_goal_on_each_calibrated_profile)
    assert calm["tracking_error_p95_m"] <= 0.04
    assert wind["tracking_error_p95_m"] <= 0.10


def test_app_main_offers_every_simulator_profile():
    from app.main import SIM_PROFILES as APP_PROFILES

    assert set(APP_PROFILES) == set(SIM_PROFILES)
