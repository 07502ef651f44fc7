"""Each autopilot gets the target-acceleration lead of its own velocity response (settings/default.yaml)."""

from __future__ import annotations

import pytest

from app.clock import LoopClock
from app.eventlog import EventLog
from app.flight import build_flight
from app.messages import TargetState
from app.missions.table import load_mission
from app.settings import SETTINGS_DIR, load_settings
from sim.autopilot_modes import Profile
from sim.inproc import InProcessVehicle
from sim.wind import WindConfig

LOOPTIME = pytest.mark.looptime(noop_cycles=2)


class Accelerating:
    """A target right where the vehicle is, at rest, accelerating north at 1 m/s²."""

    name = "accelerating"

    def __init__(self, pos_ned_m):
        self.pos_ned_m = pos_ned_m

    def target_at(self, t_s):
        return TargetState(t_s, self.pos_ned_m, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0))

    def observe(self, sample):
        pass


async def desired_north(profile: Profile, settings_file: str) -> float:
    vehicle = InProcessVehicle(profile=profile, wind=WindConfig.off())
    clock = LoopClock()
    boundary, setpoints, _ = build_flight(
        vehicle, load_mission("circle"), load_settings(SETTINGS_DIR / settings_file), clock, EventLog(None)
    )
    await vehicle.wait_ready(10.0)
    await clock.sleep(0.5)
    setpoints.engage(Accelerating(boundary.telemetry().pos_vel.pos_ned_m))
    return setpoints._guide(clock.now_s())[0][0]


@LOOPTIME
async def test_ardupilot_leads_by_its_shaping_lag_and_px4_by_its_velocity_loop_lag():
    # ArduPilot: v_t + τ·a_t with τ = 0.2 s (GUIDED's 1/K_a = WPNAV_ACCEL / PSC_JERK_XY = 2.5 / 20, which the
    # settings set, and some of its delay) and nothing else added
    assert await desired_north(Profile.ARDUPILOT, "default.yaml") == pytest.approx(0.2, abs=1e-6)
    # PX4: τ = 0.7 s, and its velocity-error feedback K_v = 2 on top (bounded at 1 m/s): 0.7 + 1.0
    assert await desired_north(Profile.PX4, "default.yaml") == pytest.approx(1.7, abs=1e-3)


@LOOPTIME
async def test_a_profile_without_a_per_autopilot_lead_uses_the_common_one():
    # thesis-guidance.yaml: velocity_lead_s 0 and no compensation — the thesis law for both autopilots
    assert await desired_north(Profile.ARDUPILOT, "thesis-guidance.yaml") == pytest.approx(0.0, abs=1e-6)
    assert await desired_north(Profile.PX4, "thesis-guidance.yaml") == pytest.approx(0.0, abs=1e-6)
