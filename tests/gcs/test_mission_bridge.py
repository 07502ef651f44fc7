"""The ground station's commands through the mission (``app.gcs.mission``), in virtual time on the in-process
vehicle: each command goes in as the link receives it (``GroundLink.answer``: parsing, dedupe, the runner's
answer), and what happened is checked from the vehicle's side. The network half is in ``test_link*.py`` and the
end-to-end test.
"""

from __future__ import annotations

import asyncio
import json
import random

import pytest

from app.clock import LoopClock
from app.eventlog import EventLog
from app.flight import fly_mission
from app.gcs.config import GcsSettings
from app.gcs.mission import MissionBridge
from app.gcs.protocol import Ack
from app.messages import FlightMode
from app.missions.table import load_mission
from app.settings import load_settings
from sim.inproc import InProcessVehicle
from sim.pickup_world import PickupScenario, PickupWorld
from sim.wind import WindConfig
from tests.app.missions.test_pickup_safety import CALM, OFFBOARD_STATES
from tests.app.missions.test_preemption import assert_zero_then_hold, commands, mode_commands
from tests.gcs.test_link import _malformed

LOOPTIME = pytest.mark.looptime(noop_cycles=2)
GCS = GcsSettings.from_mapping({"broker_url": "mqtt://127.0.0.1:1", "vehicle_id": "t1"})


def send(bridge: MissionBridge, cmd: str, cmd_id: str, **fields) -> Ack:
    return bridge.link.answer(json.dumps({"cmd": cmd, "id": cmd_id, **fields}).encode())


class Flight:
    """A calm pickup with a ground station configured; ``script(bridge, vehicle)`` drives it."""

    def __init__(self, scenario: PickupScenario | None = None, **params) -> None:
        self.scenario = scenario or PickupScenario(seed=2, **CALM)
        self.settings = load_settings()
        self.vehicle = InProcessVehicle(seed=self.scenario.seed, wind=WindConfig.off())
        self.world = PickupWorld(self.vehicle, self.scenario, self.settings)
        self.events = EventLog(None)
        self.records: list[dict] = []
        self.events.subscribe(("state", "run", "gcs"), self.records.append)
        table = load_mission("pickup")
        self.table = table.model_copy(update={"params": table.params.model_copy(update=params)})
        self.bridges: list[MissionBridge] = []

    async def run(self, script):
        clock = LoopClock()
        task = asyncio.create_task(
            fly_mission(
                self.vehicle, self.table, self.settings, clock, self.events,
                on_start=lambda r: self.bridges.append(MissionBridge(GCS, r, clock, self.events)),
                sensors=[self.world.sensors],
            )
        )  # fmt: skip
        while not self.bridges or not self.bridges[0].runner.state:  # the runner runs: in WAIT_FOR_START
            assert not task.done(), task.result().result
            await asyncio.sleep(0.01)
        await script(self.bridges[0], self.vehicle, task)
        return await task

    def states(self) -> list[tuple[float, str]]:
        return [(r["t_s"], r["to"]) for r in self.records if r["kind"] == "state"]


async def until_state(bridge: MissionBridge, state: str, task: asyncio.Task, limit_s: float = 600.0) -> float:
    loop = asyncio.get_running_loop()
    t0 = loop.time()
    while bridge.runner.state != state:
        assert not task.done(), f"ended before {state}: {task.result().result}"
        assert loop.time() - t0 < limit_s, f"no {state} within {limit_s} s"
        await asyncio.sleep(0.01)
    return loop.time()


@LOOPTIME
async def test_with_a_ground_station_it_waits_on_the_ground_for_start_then_searches_where_start_says():
    f = Flight()
    seen = {}

    async def script(bridge, vehicle, task):
        await asyncio.sleep(30.0)
        seen["state"], seen["armed"] = bridge.runner.state, vehicle.truth().armed
        seen["commands"] = commands(vehicle)
        seen["early"] = [send(bridge, "hold", "h1"), send(bridge, "authorize_land", "a1")]
        seen["bad_start"] = send(bridge, "start", "s0", search_radius_m=2000.0)  # valid MQTT, not for the mission
        seen["start"] = send(bridge, "start", "s1", start_ne_m=[47.0, 28.0])
        seen["again_same_id"] = send(bridge, "start", "s1", start_ne_m=[47.0, 28.0])
        seen["again"] = send(bridge, "start", "s2")
        await until_state(bridge, "SEARCH", task)
        seen["at_search_ne"] = vehicle.truth().pos_ned_m[:2]

    flight = await f.run(script)
    print(seen["early"], seen["bad_start"], flight.result.states_visited)
    # 30 s after launch, nothing was commanded: still on the ground, disarmed, waiting
    assert seen["state"] == "WAIT_FOR_START" and not seen["armed"] and seen["commands"] == []
    assert [a.accepted for a in seen["early"]] == [False, False]
    assert seen["early"][0].reason == "not flying (WAIT_FOR_START)"
    assert seen["early"][1].reason == "the mission pickup lands without authorisation"
    assert not seen["bad_start"].accepted and "search_max_radius_m" in seen["bad_start"].reason
    assert seen["start"].accepted and seen["again_same_id"] == seen["start"]  # a duplicate id: run once
    assert not seen["again"].accepted and seen["again"].reason.startswith("already started")
    assert sum(1 for r in f.records if r.get("event") == "start_given") == 1
    n, e = seen["at_search_ne"]
    assert abs(n - 47.0) < 1.5 and abs(e - 28.0) < 1.5  # the search began where the start command said
    assert flight.result.outcome == "picked_up"


@LOOPTIME
@pytest.mark.parametrize("state", ["TAKEOFF", *OFFBOARD_STATES, "LAND_HOME"])
async def test_abort_over_the_ground_station_in_every_flying_state_ends_in_hold(state):
    scenario = PickupScenario(seed=2, fail_first_grabs=1 if state == "REGRAB" else 0, **CALM)
    f = Flight(scenario)
    seen = {}

    async def script(bridge, vehicle, task):
        assert send(bridge, "start", "go").accepted
        await until_state(bridge, state, task)
        if state != "REGRAB":  # left for DESCEND at once when the lock holds
            await asyncio.sleep(0.3)
        seen["t_s"] = asyncio.get_running_loop().time() - 1e-6
        seen["ack"] = send(bridge, "abort", "stop")
        seen["again"] = send(bridge, "hold", "h")

    flight = await f.run(script)
    assert seen["ack"].accepted and not seen["again"].accepted and seen["again"].reason == "the mission is aborting"
    assert flight.result.outcome == "aborted" and flight.result.final_state == "ABORT"
    vehicle = f.vehicle
    if state in OFFBOARD_STATES:
        assert_zero_then_hold(vehicle, seen["t_s"])
    else:
        assert [r for r in mode_commands(vehicle, seen["t_s"]) if r["mode"] == FlightMode.HOLD.value]
    assert vehicle.truth().flight_mode is FlightMode.HOLD


@LOOPTIME
async def test_with_landing_authorisation_required_it_tracks_until_authorised_then_descends_and_picks_up():
    f = Flight(land_authorization=True)
    seen = {}

    async def script(bridge, vehicle, task):
        assert send(bridge, "start", "go").accepted
        await until_state(bridge, "TRACK", task)
        await asyncio.sleep(20.0)  # converged and right above it long since: only the operator holds it back
        seen["state"] = bridge.runner.state
        seen["waiting"] = [r for r in f.records if r.get("event") == "awaiting_land_authorization"]
        seen["t_s"] = asyncio.get_running_loop().time()
        seen["ack"] = send(bridge, "authorize_land", "land")
        seen["again"] = send(bridge, "authorize_land", "land2")

    flight = await f.run(script)
    assert seen["state"] == "TRACK" and len(seen["waiting"]) == 1
    assert seen["ack"].accepted and seen["again"].reason == "landing is already authorised"
    descends = [t for t, s in f.states() if s == "DESCEND"]
    assert descends and min(descends) >= seen["t_s"]  # never before the authorisation
    assert flight.result.outcome == "picked_up"


@LOOPTIME
async def test_a_pilot_switch_and_a_command_together_the_pilot_wins_and_the_command_is_refused():
    f = Flight()
    seen = {}

    async def script(bridge, vehicle, task):
        assert send(bridge, "start", "go").accepted
        await until_state(bridge, "TRACK", task)
        await asyncio.sleep(0.3)
        seen["t_s"] = asyncio.get_running_loop().time() - 1e-6
        vehicle.pilot_set_mode(FlightMode.POSCTL)
        seen["acks"] = [send(bridge, c, c) for c in ("hold", "rtl", "abort", "authorize_land")]
        await asyncio.sleep(5.0)
        seen["mode"] = vehicle.truth().flight_mode
        seen["state"] = bridge.runner.state
        seen["handback_t_s"] = asyncio.get_running_loop().time()
        vehicle.pilot_set_mode(FlightMode.OFFBOARD)  # hand back

    flight = await f.run(script)
    assert [(a.accepted, a.reason) for a in seen["acks"]] == [(False, "the pilot has control")] * 4
    assert seen["state"] == "MANUAL" and seen["mode"] is FlightMode.POSCTL
    # from the vehicle's side: while the pilot flew, the only mode change was the pilot's own
    while_piloted = [
        r
        for r in f.vehicle.records
        if r["event"] == "command" and r["command"] == "DO_SET_MODE" and seen["t_s"] < r["t_s"] < seen["handback_t_s"]
    ]
    assert [(r["source"], r["mode"]) for r in while_piloted] == [("pilot", "POSCTL")]
    assert flight.result.outcome == "picked_up"  # handed back, the mission went on


@LOOPTIME
async def test_1000_malformed_commands_mid_flight_are_each_refused_and_change_nothing():
    """In TRACK, 1000 bad payloads of every kind: each a rejected ack; the mission stays where it was, the
    vehicle receives nothing new from them, and the pickup goes on. The telemetry the operator gets meanwhile
    carries the position, the estimate and the battery."""
    f = Flight()
    seen = {}

    async def script(bridge, vehicle, task):
        assert send(bridge, "start", "go").accepted
        await until_state(bridge, "TRACK", task)
        rng = random.Random(7)
        before = (bridge.runner.state, bridge.runner.states_visited[:], bridge.runner.params)
        seen["acks"] = [bridge.link.answer(_malformed(rng)) for _ in range(1000)]
        seen["same"] = before == (bridge.runner.state, bridge.runner.states_visited, bridge.runner.params)
        await until_state(bridge, "DESCEND", task)
        while vehicle.truth().pos_ned_m[2] < -3.5:  # down into the radar's range
            assert bridge.runner.state == "DESCEND"
            await asyncio.sleep(0.1)
        seen["telemetry"] = bridge.telemetry()

    flight = await f.run(script)
    assert seen["same"] and all(not a.accepted and a.reason for a in seen["acks"])
    assert f.bridges[0].link.counters.malformed == 1000 and f.bridges[0].link.counters.commands == 1
    assert not [r for r in f.records if r["kind"] == "gcs" and r["cmd"] != "start"]  # none reached the runner
    t = seen["telemetry"]
    assert t.target is not None and t.height_above_sea_m is not None and t.height_above_sea_m > 1.0
    assert t.battery is not None and 14.0 < t.battery.voltage_v < 17.0 and 0.5 < t.battery.remaining_frac <= 1.0
    assert flight.result.outcome == "picked_up"
