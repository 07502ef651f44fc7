"""The pickup's safety, checked from the vehicle's side (what the in-process autopilot received): an abort in
every flying state ends in a safe state, a pilot's takeover in TRACK is obeyed and handed back, and a ground
station's hold / resume / rtl requests are carried out (or refused with the reason, changing nothing)."""

from __future__ import annotations

import asyncio

import pytest

from app.clock import LoopClock
from app.eventlog import EventLog
from app.flight import fly_mission
from app.messages import FlightMode
from app.missions.table import load_mission
from app.settings import load_settings
from sim.inproc import InProcessVehicle
from sim.pickup_world import PickupScenario, PickupWorld
from sim.wind import WindConfig
from tests.app.missions.test_preemption import assert_zero_then_hold, mode_commands, setpoints

LOOPTIME = pytest.mark.looptime(noop_cycles=2)
CALM = {"sea_state": 0, "current_mps": 0.1, "object_start_ne_m": (55.0, 20.0)}  # 15 m past where the search starts
OFFBOARD_STATES = [
    "CALIBRATE_RADAR",
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
    world = PickupWorld(vehicle, scenario, settings)
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


@LOOPTIME
async def test_hold_request_in_track_stops_in_the_autopilots_hold_and_resume_goes_on_to_the_pickup():
    scenario = PickupScenario(seed=2, **CALM)
    held = {}

    def hold(runner, vehicle):
        held["answer"] = runner.request("hold")
        held["t_s"] = asyncio.get_running_loop().time()

        async def resume():
            await asyncio.sleep(4.0)
            held["mode"] = vehicle.truth().flight_mode
            held["speed_mps"] = max(abs(v) for v in vehicle.truth().vel_ned_mps)
            held["state"] = runner.state
            held["sent_meanwhile"] = [s for s in setpoints(vehicle, held["t_s"] + 0.6) if any(s["vel_ned_mps"])]
            held["resume_t_s"] = asyncio.get_running_loop().time()
            held["resume"] = runner.request("resume")

        asyncio.get_running_loop().create_task(resume())

    flight, vehicle, t_s = await fly_until("TRACK", hold, scenario)
    visited = flight.result.states_visited
    print(held, visited)
    assert held["answer"] is None and held["resume"] is None
    assert held["state"] == "HOLD" and held["mode"] is FlightMode.HOLD and held["speed_mps"] < 0.2
    assert held["sent_meanwhile"] == []  # after the zero-velocity stop, nothing that moves
    assert_zero_then_hold(vehicle, t_s, until_s=held["resume_t_s"])  # leaving offboard: zero, then HOLD
    i = visited.index("HOLD")
    assert visited[i - 1 : i + 2] == ["TRACK", "HOLD", "TRACK"]
    assert flight.result.outcome == "picked_up"


@LOOPTIME
async def test_rtl_request_in_search_flies_home_and_lands_without_the_object():
    scenario = PickupScenario(seed=2, **CALM)
    answers = []
    flight, vehicle, _ = await fly_until("SEARCH", lambda r, v: answers.append(r.request("rtl")), scenario, 0.0)
    visited = flight.result.states_visited
    assert answers == [None]
    assert visited[visited.index("SEARCH") + 1 :] == ["RETURN", "LAND_HOME", "RETURNED_EMPTY"], visited
    truth = vehicle.truth()
    assert not truth.armed and abs(truth.pos_ned_m[0]) < 1.5 and abs(truth.pos_ned_m[1]) < 1.5  # landed at home


@LOOPTIME
async def test_requests_that_do_not_fit_the_state_are_refused_with_the_reason_and_change_nothing():
    scenario = PickupScenario(seed=2, **CALM)
    answers = {}

    def ask(runner, vehicle):
        answers["resume"] = runner.request("resume")
        answers["land_now"] = runner.request("land_now")
        answers["state"] = runner.state
        vehicle.pilot_set_mode(FlightMode.POSCTL)

        async def while_the_pilot_flies():
            await asyncio.sleep(1.0)
            answers["hold_under_pilot"] = runner.request("hold")
            answers["state_under_pilot"] = runner.state
            vehicle.pilot_set_mode(FlightMode.OFFBOARD)

        asyncio.get_running_loop().create_task(while_the_pilot_flies())

    flight, _, _ = await fly_until("APPROACH", ask, scenario, 0.0)
    print(answers)
    assert answers["resume"] == "nothing to resume in APPROACH" and answers["state"] == "APPROACH"
    assert answers["land_now"] == "the mission pickup has no 'land_now' request"
    assert answers["hold_under_pilot"] == "the pilot has control" and answers["state_under_pilot"] == "MANUAL"
    assert "HOLD" not in flight.result.states_visited and flight.result.outcome == "picked_up"


@LOOPTIME
async def test_abort_while_held_ends_in_hold_and_stays_there():
    scenario = PickupScenario(seed=2, **CALM)

    def hold_then_abort(runner, vehicle):
        assert runner.request("hold") is None

        async def abort():
            await asyncio.sleep(2.0)
            runner.request_abort("test")

        asyncio.get_running_loop().create_task(abort())

    flight, vehicle, _ = await fly_until("SEARCH", hold_then_abort, scenario)
    assert flight.result.states_visited[-3:] == ["SEARCH", "HOLD", "ABORT"]
    assert flight.result.outcome == "aborted" and vehicle.truth().flight_mode is FlightMode.HOLD


@LOOPTIME
async def test_a_vehicle_disarmed_in_flight_ends_the_mission_and_is_sent_nothing_more():
    """The pilot's kill switch in TRACK (or an autopilot's auto-disarm on the water): the mission ends in
    DISARMED (failed) at once, and from the vehicle's side no command or mode change follows the disarm — only
    the re-sent setpoint, zeroed."""
    flight, vehicle, t_s = await fly_until("TRACK", lambda runner, v: v.pilot_kill(), PickupScenario(seed=1, **CALM))
    print(flight.result, [r for r in vehicle.records if r["t_s"] >= t_s and r["event"] != "setpoint"])
    assert flight.result.outcome == "failed" and flight.result.final_state == "DISARMED"
    assert flight.result.states_visited[-2:] == ["TRACK", "DISARMED"]
    after = [r for r in vehicle.records if r["t_s"] >= t_s]
    kill = next(r for r in after if r["event"] == "command")
    assert kill["command"] == "COMPONENT_ARM_DISARM" and kill["source"] == "pilot"
    assert [r for r in after if r["event"] in ("command", "mode") and r is not kill] == []
    sent = [r for r in after if r["event"] == "setpoint"]
    print(sent[-3:])
    assert sent[-1]["vel_ned_mps"] == [0.0, 0.0, 0.0] and sent[-1]["origin"] == "watchdog"
