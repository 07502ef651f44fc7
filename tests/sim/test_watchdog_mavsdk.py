"""The setpoint watchdog thread over real MAVSDK and UDP: a blocked event loop gets the re-sent setpoint
zeroed, as the simulated autopilot's state log shows (wall-clock stamped on the vehicle's side)."""

from __future__ import annotations

import asyncio
import json
import time

from app.clock import LoopClock
from app.eventlog import EventLog
from app.flight import build_flight
from app.messages import FlightMode
from app.missions.table import load_mission
from app.settings import Settings
from sim.wind import WindConfig
from tests.sim.conftest import app_vehicle_on_sim, eventually


async def test_a_blocked_event_loop_gets_the_resent_setpoint_zeroed_by_the_watchdog_thread(tmp_path):
    log = tmp_path / "sim_state.jsonl"
    settings, clock, events = Settings(), LoopClock(), EventLog(None)
    async with app_vehicle_on_sim(settings, clock, events, state_log=str(log), wind=WindConfig.off(), seed=1) as (
        _,
        vehicle,
    ):
        boundary, _, _ = build_flight(vehicle, load_mission("circle"), settings, clock, events)
        boundary.flying = True
        await boundary.arm()
        await boundary.takeoff(3.0)
        await eventually(lambda: vehicle.telemetry().mode() is FlightMode.HOLD, 30.0)
        await boundary.start_offboard()
        for _ in range(50):  # 1 s at 1 m/s north
            await boundary.send_velocity((1.0, 0.0, 0.0), 0.0)
            await asyncio.sleep(0.02)
        t_block = time.time()
        time.sleep(1.0)  # noqa: ASYNC251 — the event loop is blocked on purpose: nothing on it runs
        t_unblock = time.time()
        for _ in range(10):
            await boundary.send_velocity((1.0, 0.0, 0.0), 0.0)
            await asyncio.sleep(0.02)
        await boundary.release("test")
    sps = [r for r in map(json.loads, log.read_text().splitlines()) if r["event"] == "setpoint"]
    during = [r for r in sps if t_block <= r["t_wall"] <= t_unblock]
    zeros = [r for r in during if r["vel_ned_mps"] == [0.0, 0.0, 0.0]]
    assert zeros, f"{len(during)} setpoints during the block, none zero"
    latency_s = zeros[0]["t_wall"] - t_block
    print(f"watchdog: zero velocity reached the vehicle {latency_s:.3f} s into a 1 s loop block (wall clock)")
    assert latency_s < 0.6  # 0.2 s timeout + 20 ms poll; generous for a loaded machine
    assert all(r["vel_ned_mps"] == [0.0, 0.0, 0.0] for r in during if r["t_wall"] > zeros[0]["t_wall"])
    assert boundary.watchdog.fired_count == 1
    after = [r for r in sps if r["t_wall"] > t_unblock + 0.1]
    assert any(r["vel_ned_mps"][0] > 0.9 for r in after)  # the app was back, then released: zeros
    assert after[-1]["vel_ned_mps"] == [0.0, 0.0, 0.0]
