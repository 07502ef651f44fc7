"""The pickup's safety, checked from the vehicle's side (what the in-process autopilot received): an abort in
every flying state ends in a safe state, and a pilot's takeover in TRACK is obeyed and handed back."""

from __future__ import annotations

import asyncio

import pytest

from app.clock import LoopClock
from app.eventlog import EventLog
from app.main import fly_mission
from app.messages import FlightMode
from app.missions.table import load_mission
from app.settings import load_settings
from sim.inproc import InProcessVehicle
from sim.pickup_world import PickupScenario, PickupWorld
from sim.wind import WindConfig
from tests.app.missions.test_preemption import assert_zero_then_hold, mode_commands, setpoints

LOOPTIME = pytest.mark.looptime(noop_cycles=2)
CALM = {"sea_state": 0, "current_mps": 0.1}
OFFBOARD_STATES = [
    "GOTO_SEARCH",
    "SEARCH",
    "APPROACH",
    "TRACK",
    "DESCEND",
    "GRAB",
    "VERIFY",
    "REGRAB",
    "LIFT",
    "RETURN",
]


async def fly_until(state: str, then, scenario: PickupScenario, after_s: float = 0.3, events: EventLog | None = None):
    """Fly the calm pickup; once the mission has been in ``state`` for ``after_s``, call ``then(runner, vehicle)``."""
    settings = load_settings()
    vehicle = InProcessVehicle(seed=scenario.seed, wind=WindConfig.off())
    world = PickupWorld(vehicle, scenario, settings.camera, settings.detector)
    runners = []
    task = asyncio.create_task(
        fly_mission(
            vehicle, load_mission("pickup"), settings, LoopClock(), events or EventLog(None),
            on_start=runners.append, sensors=[world.sensors],
        )
    )  # fmt: skip
    loop = asyncio.get_running_loop()
    while not runners or runners[0].state != state:
        assert not task.done(), f"the mission ended without reaching {state}: {task.result().result}"
        await asyncio.sleep(0.01)
    await asyncio.sleep(after_s)
    t_s = loop.time()
    assert runners[0].state == state
    then(runners[0], vehicle)
    return await task, vehicle, t_s - 1e-6  # what the vehicle received from this instant on


@LOOPTIME
@pytest.mark.parametrize("state", ["TAKEOFF", *OFFBOARD_STATES, "LAND_HOME"])
async def test_abort_in_every_flying_state_ends_in_hold(state):
    scenario = PickupScenario(seed=2, fail_first_grabs=1 if state == "REGRAB" else 0, **CALM)
    after_s = 0.0 if state == "REGRAB" else 0.3  # REGRAB is left for DESCEND at once when the lock holds
    flight, vehicle, t_abort = await fly_until(state, lambda r, v: r.request_abort("test"), scenario, after_s)
    assert flight.result.outcome == "aborted" and flight.result.final_state == "ABORT"
    if state in OFFBOARD_STATES:  # leaving offboard: zero velocity first, then HOLD
        assert_zero_then_hold(vehicle, t_abort)
    else:
        holds = [r for r in mode_commands(vehicle, t_abort) if r["mode"] == FlightMode.HOLD.value]
        assert holds, "no HOLD after the abort"
        assert not [s for s in setpoints(vehicle, t_abort) if any(s["vel_ned_mps"])]  # nothing moving sent
    assert vehicle.truth().flight_mode is FlightMode.HOLD


@LOOPTIME
async def test_pilot_takeover_in_track_is_obeyed_then_handback_resumes_and_picks_up():
    scenario = PickupScenario(seed=2, **CALM)
    taken = {}

    def take_over(runner, vehicle):
        vehicle.pilot_set_mode(FlightMode.POSCTL)
        taken["t_s"] = asyncio.get_running_loop().time()

        async def hand_back():
            await asyncio.sleep(3.0)
            taken["sent_meanwhile"] = [
                s for s in setpoints(vehicle, taken["t_s"] + 0.05) if any(s["vel_ned_mps"]) and s["origin"] == "app"
            ]
            vehicle.pilot_set_mode(FlightMode.OFFBOARD)

        asyncio.get_running_loop().create_task(hand_back())

    flight, _, _ = await fly_until("TRACK", take_over, scenario)
    visited = flight.result.states_visited
    print(visited, flight.figures)
    assert taken["sent_meanwhile"] == []  # while the pilot flew, the app sent nothing that moves
    i = visited.index("MANUAL")
    assert visited[i - 1 : i + 2] == ["TRACK", "MANUAL", "TRACK"]
    assert flight.result.outcome == "picked_up"
