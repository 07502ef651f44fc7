"""The runner drives the in-process simulated vehicle on the loop clock: whole missions in virtual time."""

from __future__ import annotations

import asyncio
import time
from dataclasses import replace

import pytest

from app.clock import LoopClock
from app.eventlog import EventLog
from app.flight import fly_mission
from app.messages import FlightMode
from app.missions.table import load_mission
from app.settings import Settings
from sim.inproc import InProcessVehicle
from sim.wind import WindConfig


class RecordingVehicle(InProcessVehicle):
    """The in-process vehicle, also keeping every setpoint the app sent with its loop time."""

    def __init__(self, **kw):
        super().__init__(**kw)
        self.sent: list[tuple[float, tuple[float, float, float]]] = []

    async def set_velocity_ned(self, vel_ned_mps, yaw_rad):
        self.sent.append((asyncio.get_running_loop().time(), tuple(vel_ned_mps)))
        await super().set_velocity_ned(vel_ned_mps, yaw_rad)


async def fly(vehicle, mission="circle", events=None):
    return await fly_mission(vehicle, load_mission(mission), Settings(), LoopClock(), events or EventLog(None))


@pytest.mark.looptime(noop_cycles=2)
async def test_sixty_seconds_of_mission_pass_in_under_two_seconds_of_wall_time():
    vehicle = InProcessVehicle(seed=1)
    wall0, loop0 = time.perf_counter(), asyncio.get_running_loop().time()
    flight = await fly(vehicle)
    wall_s, mission_s = time.perf_counter() - wall0, asyncio.get_running_loop().time() - loop0
    assert flight.result.outcome == "completed"
    assert flight.result.states_visited == ["PREFLIGHT", "TAKEOFF", "TRACK", "LAND", "DONE"]
    assert mission_s >= 60.0
    print(f"{mission_s:.0f} s of mission in {wall_s:.2f} s of wall time ({mission_s / wall_s:.0f}× real time)")
    assert wall_s < mission_s / 5.0, f"{mission_s:.0f} s of mission took {wall_s:.2f} s"  # generous: a loaded machine
    assert not vehicle.truth().armed


@pytest.mark.looptime(noop_cycles=2)
async def test_circle_tracking_error_in_still_air():
    flight = await fly(InProcessVehicle(seed=1, wind=WindConfig.off()))
    assert flight.figures["tracking_samples"] > 1000
    assert flight.figures["tracking_error_p95_m"] <= 0.04


@pytest.mark.looptime(noop_cycles=2)
async def test_pilot_takeover_stops_guidance_and_handback_resumes_tracking():
    vehicle = RecordingVehicle(seed=2)
    task = asyncio.create_task(fly(vehicle))
    clock = LoopClock()
    while vehicle.truth().flight_mode != FlightMode.OFFBOARD:
        await clock.sleep(0.1)
    await clock.sleep(5.0)
    vehicle.pilot_set_mode(FlightMode.POSCTL)
    t_switch = clock.now_s()
    await clock.sleep(10.0)
    # The pilot keeps POSCTL: the app never switched the mode back and only sent standby setpoints.
    assert vehicle.truth().flight_mode == FlightMode.POSCTL
    after = [v for t, v in vehicle.sent if t > t_switch + 0.1]
    assert 40 <= len(after) <= 10.0 * 5 + 2, len(after)  # the 5 Hz standby stream, not 50 Hz guidance
    assert all(v == (0.0, 0.0, 0.0) for v in after)
    vehicle.pilot_set_mode(FlightMode.OFFBOARD)
    flight = await task
    assert flight.result.outcome == "completed"
    assert flight.result.states_visited == ["PREFLIGHT", "TAKEOFF", "TRACK", "MANUAL", "TRACK", "LAND", "DONE"]


class HeartbeatArmedVehicle(InProcessVehicle):
    """Armed state sampled at 1 Hz (HEARTBEAT), the flight mode at once (PX4's CURRENT_MODE)."""

    def __init__(self, **kw):
        super().__init__(**kw)
        self._armed = None

    def telemetry(self):
        tel = super().telemetry()
        if self._armed is None or tel.armed.t_s - self._armed.t_s >= 1.0:
            self._armed = tel.armed
        return replace(tel, armed=self._armed)


@pytest.mark.looptime(noop_cycles=2)
async def test_hold_on_disarm_after_landing_seen_before_disarmed_is_not_a_takeover():
    """PX4 switches to HOLD as it auto-disarms after a landing; the mode can arrive up to a second before the
    armed flag does. On the ground only a pilot mode means someone took over."""
    flight = await fly(HeartbeatArmedVehicle(seed=1))
    assert flight.result.outcome == "completed", flight.result
    assert flight.result.states_visited == ["PREFLIGHT", "TAKEOFF", "TRACK", "LAND", "DONE"]
