"""The whole pickup in virtual time on the in-process vehicle, with the geometric camera and radar heights
(``sim.pickup_world``): search, approach, track, descend onto the drifting object, grab, lift, fly home, land.
"""

from __future__ import annotations

import asyncio
import itertools
import math
import time

import numpy as np
import pytest

from app.clock import LoopClock
from app.eventlog import EventLog
from app.flight import fly_mission
from app.messages import FlightMode
from app.missions.table import load_mission
from app.offboard.guidance import ConstantBearingParams, approach_speed_mps
from app.report import read_jsonl
from app.settings import Settings, load_settings
from sim.airframes import SIM_PROFILES
from sim.autopilot_modes import Profile
from sim.inproc import InProcessVehicle
from sim.pickup_world import PickupScenario, PickupWorld
from sim.wind import WindConfig


async def fly_pickup(
    scenario: PickupScenario,
    wind: WindConfig | None,
    profile: str = "px4",
    events: EventLog | None = None,
    settings: Settings | None = None,
    observers: tuple = (),
    **params,
):
    settings = settings or load_settings()
    calibrated = SIM_PROFILES[profile]
    vehicle = InProcessVehicle(
        seed=scenario.seed, wind=wind, profile=calibrated.autopilot, vehicle_params=calibrated.airframe
    )
    world = PickupWorld(vehicle, scenario, settings)
    world.frame_observers.extend(observers)  # (t_s, the vehicle's truth, the object's) at every camera frame
    table = load_mission("pickup")
    table = table.model_copy(update={"params": table.params.model_copy(update=params)})
    runners = []
    flight = await fly_mission(
        vehicle,
        table,
        settings,
        LoopClock(),
        events or EventLog(None),
        on_start=runners.append,
        sensors=[world.sensors],
    )
    world.model = runners[0].mission  # the mission's estimates, for checks against the truth
    return flight, world, table.params


def assert_never_descends_low_without_a_fresh_fix(world: PickupWorld, p) -> None:
    """From the vehicle's side: never descending onto the sea below the safety height without a fresh fix
    (until the first grab; LAND_HOME is the autopilot landing at home, not on the object)."""
    grab_s, fixes = world.outcome.grabs[0]["t_s"], np.array(world.model.fix_times_s)
    for t_s, height_m, down_mps, _ in world.samples:
        if t_s < grab_s and height_m < p.safety_height_m - 0.3 and down_mps > 0.2:
            before = fixes[fixes <= t_s]
            fix_age_s = t_s - before[-1] if len(before) else None
            assert fix_age_s is not None and fix_age_s <= p.fix_fresh_s + 0.5, (t_s, height_m, down_mps, fix_age_s)


@pytest.mark.looptime(noop_cycles=2)
async def test_calm_sea_pickup_goes_through_every_state_and_catches_the_object():
    wall0 = time.perf_counter()
    # the object 15 m past where the search starts: found in SEARCH (from 15 m the camera sees 14 m × 19 m of sea)
    scenario = PickupScenario(seed=1, sea_state=0, current_mps=0.1, object_start_ne_m=(55.0, 20.0))
    flight, world, p = await fly_pickup(scenario, WindConfig.off())
    wall_s = time.perf_counter() - wall0
    out = world.outcome
    print(f"{flight.result.states_visited}; {flight.duration_s:.0f} s of mission in {wall_s:.1f} s")
    print(f"touchdown error {out.touchdown_error_m:.3f} m at {out.touchdown_speed_mps:.2f} m/s; {flight.figures}")
    assert flight.result.outcome == "picked_up"
    assert flight.result.states_visited == [
        "WAIT_FOR_START", "TAKEOFF", "CALIBRATE_RADAR", "GOTO_SEARCH", "SEARCH", "APPROACH", "TRACK", "DESCEND",
        "GRAB", "VERIFY", "LIFT", "RETURN", "LAND_HOME", "DONE",
    ]  # fmt: skip
    assert flight.figures["picked_up"] and flight.figures["retries"] == 0
    drops, puts = flight.figures["queue_drops"], flight.figures["queue_puts"]
    # the radar sees the sea only within its 5 m: below the search height
    assert puts["camera"] > 1000 and puts["radar"] > 300 and drops == {"camera": 0, "radar": 0}
    assert out.caught and len(out.grabs) == 1
    assert out.touchdown_error_m <= world.scenario.capture_radius_m  # the goal is 0.10 m: not yet
    assert_never_descends_low_without_a_fresh_fix(world, p)


@pytest.mark.looptime(noop_cycles=2)
@pytest.mark.parametrize("profile", ["px4", "ardupilot"])
async def test_it_flies_to_the_search_and_home_at_the_transit_speed_and_stops_over_home(profile):
    """GOTO_SEARCH and RETURN fly at the cruise speed (``transit_speed_mps``, PX4's MPC_XY_CRUISE) rather than at
    guidance's approach speed; the search is taken up at the search speed and the return brakes to a stop over
    home: seen in the vehicle's truth, not in our log."""
    events = EventLog(None)
    states: list[dict] = []
    events.subscribe({"state"}, states.append)
    track: list[tuple[float, tuple, tuple]] = []
    scenario = PickupScenario(seed=1, sea_state=0, current_mps=0.1, object_start_ne_m=(55.0, 20.0))
    flight, _, p = await fly_pickup(
        scenario,
        WindConfig.off(),
        profile,
        events=events,
        observers=(lambda t_s, s, _o: track.append((t_s, tuple(s.pos_ned_m), tuple(s.vel_ned_mps))),),
    )
    assert flight.result.outcome == "picked_up"
    spans = {a["to"]: (a["t_s"], b["t_s"]) for a, b in itertools.pairwise(states)}
    envelope_mps = load_settings().envelope.max_horizontal_speed_mps
    t0_s, t1_s = spans["GOTO_SEARCH"]
    out = [math.hypot(v[0], v[1]) for t, _, v in track if t0_s <= t < t1_s]
    print(f"{profile}: to the search in {t1_s - t0_s:.1f} s, top {max(out):.2f} m/s, there at {out[-1]:.2f} m/s")
    assert 0.9 * p.transit_speed_mps < max(out) < envelope_mps + 0.3
    assert abs(out[-1] - p.search_speed_mps) < 1.0  # taking the search up at its speed
    t0_s, t1_s = spans["RETURN"]
    back = [(t, pos, math.hypot(v[0], v[1])) for t, pos, v in track if t0_s <= t < t1_s]
    from_m = math.hypot(back[0][1][0], back[0][1][1])
    top_mps = max(x[2] for x in back)
    landed = track[-1][1]
    print(
        f"{profile}: {from_m:.1f} m home in {t1_s - t0_s:.1f} s, top {top_mps:.2f} m/s, "
        f"over home at {back[-1][2]:.2f} m/s, landed {math.hypot(landed[0], landed[1]):.2f} m from home"
    )
    assert from_m > 50.0
    assert 0.9 * p.transit_speed_mps < top_mps < envelope_mps + 0.3
    # the climb to the return altitude and the braking take a few seconds; at 2 m/s it took from_m / 2 and more
    assert t1_s - t0_s < from_m / p.transit_speed_mps + 8.0
    # over home (within at_point_m) it is no faster than guidance closing on a fixed point from there (1.9 m/s)
    g = load_settings().guidance
    closing_mps = approach_speed_mps(
        p.at_point_m, ConstantBearingParams(g.approach_speed_max_mps, g.transient_distance_m)
    )
    assert back[-1][2] < closing_mps + 0.3
    assert math.hypot(landed[0], landed[1]) < 1.0


@pytest.mark.looptime(noop_cycles=2)
async def test_a_failed_grab_is_seen_from_above_released_and_retried_until_it_holds():
    scenario = PickupScenario(seed=2, sea_state=0, current_mps=0.1, fail_first_grabs=1)
    flight, world, _ = await fly_pickup(scenario, WindConfig.off())
    visited = flight.result.states_visited
    print(visited, flight.figures, world.outcome.grabs)
    assert flight.result.outcome == "picked_up" and flight.figures["retries"] == 1
    i = visited.index("VERIFY")
    assert visited[i : i + 6] == ["VERIFY", "REGRAB", "DESCEND", "GRAB", "VERIFY", "LIFT"]
    assert [g["caught"] for g in world.outcome.grabs] == [False, True]


@pytest.mark.looptime(noop_cycles=2)
async def test_after_the_last_retry_it_comes_home_empty_and_says_so():
    scenario = PickupScenario(seed=2, sea_state=0, current_mps=0.1, fail_first_grabs=10)
    flight, world, p = await fly_pickup(scenario, WindConfig.off(), grab_retries=1)
    visited = flight.result.states_visited
    print(visited, flight.figures)
    assert flight.result.outcome == "failed" and flight.result.final_state == "RETURNED_EMPTY"
    assert len(world.outcome.grabs) == p.grab_retries + 1 == 2 and not flight.figures["picked_up"]
    assert visited[-5:] == ["GRAB", "VERIFY", "RETURN", "LAND_HOME", "RETURNED_EMPTY"]  # no third grab
    assert not world.vehicle.truth().armed  # landed at home


async def fly_blinded(state: str, max_height_m: float, blind_s: float, **params):
    """The calm-sea pickup (seed 1) with the camera blind for ``blind_s`` from the moment the mission is in
    ``state`` with the vehicle at most ``max_height_m`` over the sea. Returns the flight, the world and what the
    blind spell saw: its start ``t_s`` and end ``end_s``, the states visited before it (``before``, a count) and by
    its end (``states``), the heights over the sea through it (``heights_m``, the simulator's truth)."""
    settings = load_settings()
    scenario = PickupScenario(seed=1, sea_state=0, current_mps=0.1)
    vehicle = InProcessVehicle(seed=1, wind=WindConfig.off())
    world = PickupWorld(vehicle, scenario, settings)
    runners, blind = [], {}

    async def blind_spell():
        while not runners or runners[0].state != state or world.samples[-1][1] > max_height_m:  # noqa: ASYNC110
            await asyncio.sleep(0.02)  # polls the mission's state: nothing to wait on
        blind["t_s"], blind["before"] = asyncio.get_running_loop().time(), len(runners[0].states_visited)
        world.camera_blind = True
        await asyncio.sleep(blind_s)
        blind["end_s"], blind["states"] = asyncio.get_running_loop().time(), list(runners[0].states_visited)
        blind["heights_m"] = [h for t, h, _, _ in world.samples if t >= blind["t_s"]]
        world.camera_blind = False

    watcher = asyncio.create_task(blind_spell())
    table = load_mission("pickup")
    table = table.model_copy(update={"params": table.params.model_copy(update=params)})
    flight = await fly_mission(
        vehicle, table, settings, LoopClock(), EventLog(None), on_start=runners.append, sensors=[world.sensors]
    )
    watcher.cancel()
    print(blind["states"], flight.result.states_visited, world.outcome.grabs)
    return flight, world, blind


@pytest.mark.looptime(noop_cycles=2)
async def test_target_lost_low_in_descend_climbs_back_reacquires_and_still_picks_up():
    """The marker vanishes for 3 s when the vehicle is 1.5 m over the sea in DESCEND: no more descending, back
    to TRACK (climbing; after 2 s without a fix TRACK gives it up to SEARCH), and once it is seen again the
    descent starts over."""
    flight, world, blind = await fly_blinded("DESCEND", 1.5, 3.0)
    visited = flight.result.states_visited
    p = load_mission("pickup").params
    assert blind["states"][blind["before"] - 1 : blind["before"] + 1] == ["DESCEND", "TRACK"]  # lost → TRACK
    assert max(blind["heights_m"]) >= p.safety_height_m  # it climbed back to the safety height
    assert visited[visited.index("TRACK") + 1 :].count("DESCEND") >= 2  # a second descent after re-acquiring
    assert flight.result.outcome == "picked_up" and world.outcome.caught


@pytest.mark.looptime(noop_cycles=2)
async def test_grab_blind_too_long_before_the_water_climbs_back_without_closing_the_gripper():
    """The camera goes blind as GRAB begins its sink (here from 1 m over the sea, ``touchdown_height_m``, so that
    the sink takes longer than ``grab_blind_max_s``): once the newest fix is older than that, before the water, it
    gives the grab up — back to TRACK, the gripper left open — and, seeing again, descends once more and picks
    the object up. Judged from the simulator's side: no grab (gripper closed) while blind, no contact with the
    water, and the vehicle climbed back."""
    flight, world, blind = await fly_blinded("GRAB", math.inf, 2.0, touchdown_height_m=1.0)
    assert blind["states"][blind["before"] - 1 : blind["before"] + 1] == ["GRAB", "TRACK"]  # gave the grab up
    lowest_m, end_m = min(blind["heights_m"]), blind["heights_m"][-1]
    assert lowest_m > 0.05 and end_m > lowest_m + 0.3  # stopped over the water, climbing
    assert all(g["t_s"] > blind["end_s"] for g in world.outcome.grabs)  # the gripper never closed while blind
    assert all(c["t_s"] > blind["end_s"] for c in world.outcome.contacts)  # nor did it touch the water
    assert flight.result.outcome == "picked_up" and world.outcome.caught and flight.figures["retries"] == 0


@pytest.mark.parametrize("blind_max_s", ["default", None])
@pytest.mark.looptime(noop_cycles=2)
async def test_going_blind_low_in_descend_goes_on_only_if_the_grab_would_reach_the_water_seeing_enough(blind_max_s):
    """The camera goes blind for 2 s in DESCEND's final part, 0.5 m over the sea: going on, the vehicle would meet
    the water ~0.8 s after its last fix, older than the mission's ``grab_blind_max_s`` (0.5 s), so GRAB would give
    the grab up on the way down, sinking still, low over the water — where it met the water off the object (sea
    state 3, seed 10 run 130: 0.30 m off). DESCEND climbs back now (→ TRACK), while it is high enough to, and
    the descent starts over on seeing again. Without the limit (null) it goes on blind: GRAB, and the gripper
    closes on the water within the blind spell. Judged from the simulator's side (its heights and contacts)."""
    params = {} if blind_max_s == "default" else {"grab_blind_max_s": blind_max_s}
    flight, world, blind = await fly_blinded("DESCEND", 0.5, 2.0, **params)
    in_spell = [c for c in world.outcome.contacts if blind["t_s"] <= c["t_s"] <= blind["end_s"]]
    if blind_max_s == "default":
        assert load_mission("pickup").params.grab_blind_max_s == 0.5
        assert blind["states"][blind["before"] - 1 :] == ["DESCEND", "TRACK"]  # climbed back, no GRAB while blind
        assert not in_spell and min(blind["heights_m"]) > 0.25  # off the water all the while
    else:
        assert blind["states"][blind["before"] - 1 : blind["before"] + 1] == ["DESCEND", "GRAB"]
        assert in_spell and min(blind["heights_m"]) < 0.05  # down on the water, blind
    assert flight.result.outcome == "picked_up" and world.outcome.caught


async def fly_with_marker_moved_in_grab(
    tmp_path, offsets_n_m: list[float], hold_s: float, profile=Profile.PX4, settings=None, **params
):
    """The calm-sea pickup (seed 1), GRAB from 1 m over the mean sea (``touchdown_height_m``: the sink is long), and
    the marker seen moved north as GRAB begins: by ``offsets_n_m`` in turn, one per 0.02 s, then ``hold_s`` at the
    last, then back where it is. Returns the flight, the world, the states GRAB was left for (the event log's) and
    the spell: its start ``t_s`` and end ``end_s``, the heights over the sea through it (the simulator's truth).
    ``profile``: the autopilot flown; ``settings``: seapick's (the default ones when not given)."""
    settings = load_settings() if settings is None else settings
    vehicle = InProcessVehicle(seed=1, wind=WindConfig.off(), profile=profile)
    world = PickupWorld(vehicle, PickupScenario(seed=1, sea_state=0, current_mps=0.1), settings)
    runners, spell, offset_ne_m = [], {}, [0.0, 0.0, 0.0]
    seen_at = world._largest_seen
    world._largest_seen = lambda t_s, truth, centre: seen_at(
        t_s, truth, tuple(float(c) + d for c, d in zip(centre, offset_ne_m, strict=True))
    )

    async def moved_in_view():
        while not runners or runners[0].state != "GRAB":  # noqa: ASYNC110
            await asyncio.sleep(0.02)  # polls the mission's state: nothing to wait on
        spell["t_s"] = asyncio.get_running_loop().time()
        for offset_m in offsets_n_m:
            offset_ne_m[0] = offset_m
            await asyncio.sleep(0.02)
        await asyncio.sleep(hold_s)
        offset_ne_m[0] = 0.0
        spell["end_s"] = asyncio.get_running_loop().time()
        spell["heights_m"] = [h for t, h, _, _ in world.samples if spell["t_s"] <= t <= spell["end_s"]]

    watcher = asyncio.create_task(moved_in_view())
    table = load_mission("pickup")
    table = table.model_copy(update={"params": table.params.model_copy(update={"touchdown_height_m": 1.0, **params})})
    events = EventLog(tmp_path / "events.jsonl")
    flight = await fly_mission(
        vehicle, table, settings, LoopClock(), events, on_start=runners.append, sensors=[world.sensors]
    )
    watcher.cancel()
    events.close()
    left = [e for e in read_jsonl(tmp_path / "events.jsonl") if e["kind"] == "state" and e["from"] == "GRAB"]
    print(left, flight.result.states_visited, world.outcome.grabs, world.outcome.contacts, spell)
    return flight, world, left, spell


@pytest.mark.looptime(noop_cycles=2)
async def test_a_new_lock_during_the_grabs_sink_sends_it_back_up_before_the_water(tmp_path):
    """GRAB's sink follows the estimate down blind-ish: if the filter's lock is renewed on the way (here the camera
    sees the marker 0.5 m to the side for 2 s — a same-ID print, the real one out of view — and the filter escapes
    onto it), the sink is given up before the water as DESCEND's would be (``lock_renewed`` → TRACK), the gripper
    left open, and the pickup starts over on the object. Judged from the simulator's side: no grab, no contact
    with the water while the print was seen; the vehicle climbed; the object picked up in the end."""
    flight, world, left, spell = await fly_with_marker_moved_in_grab(tmp_path, [0.5], 1.98)
    assert left[0]["reason"] == "lock_renewed" and left[0]["to"] == "TRACK"
    assert spell["t_s"] < left[0]["t_s"] < spell["end_s"]
    assert all(not spell["t_s"] <= g["t_s"] <= spell["end_s"] for g in world.outcome.grabs)  # gripper kept open
    assert all(not spell["t_s"] <= c["t_s"] <= spell["end_s"] for c in world.outcome.contacts)  # off the water
    assert min(spell["heights_m"]) > 0.05 and spell["heights_m"][-1] > min(spell["heights_m"]) + 0.3  # climbing
    assert flight.result.outcome == "picked_up" and world.outcome.caught
    assert all(c["error_m"] <= world.scenario.capture_radius_m for c in world.outcome.contacts)


@pytest.mark.parametrize("abort_offset_m", [0.05, None])
@pytest.mark.looptime(noop_cycles=2)
async def test_grabs_sink_off_the_estimate_climbs_back_before_the_water(tmp_path, abort_offset_m):
    """GRAB's sink, blind with the gripper under it, does not win back a vehicle that has come off the estimate
    (ArduCopter pushed by a gust, a late fix moving the estimate): farther than ``grab_abort_offset_m`` off it, before
    the water, it gives the grab up (``grab_gone_off`` → TRACK) and the pickup starts over. Here the marker is seen
    sliding 0.15 m aside over 0.5 s as GRAB begins, the filter following it, and the limit is 0.05 m (the mission's
    0.15 m is for the sea-state-3 swell). Without the limit the gripper closes on the way, off the object. Judged
    from the simulator's side: no grab, no contact between the slide's start and GRAB's end; picked up in the end,
    every contact within the capture radius."""
    slide_n_m = [0.15 * (k + 1) / 25 for k in range(25)]
    flight, world, left, spell = await fly_with_marker_moved_in_grab(
        tmp_path, slide_n_m, 1.5, grab_abort_offset_m=abort_offset_m
    )
    if abort_offset_m is None:  # the sink went on, and the gripper closed while the marker was seen aside
        assert left[0]["reason"] == "grab_settled"
        assert spell["t_s"] < world.outcome.grabs[0]["t_s"] < spell["end_s"]
        return
    assert left[0]["reason"] == "grab_gone_off" and left[0]["to"] == "TRACK"
    assert spell["t_s"] < left[0]["t_s"] < spell["t_s"] + 0.5
    assert all(not spell["t_s"] <= g["t_s"] <= left[0]["t_s"] + 0.5 for g in world.outcome.grabs)  # gripper open
    assert all(not spell["t_s"] <= c["t_s"] <= left[0]["t_s"] + 0.5 for c in world.outcome.contacts)  # off the water
    assert flight.result.outcome == "picked_up" and world.outcome.caught
    assert all(c["error_m"] <= world.scenario.capture_radius_m for c in world.outcome.contacts)


@pytest.mark.parametrize("abort_offset_m", ["default", 0.15])
@pytest.mark.looptime(noop_cycles=2)
async def test_the_missions_grab_limit_gives_up_a_sink_that_would_grab_a_decimetre_off(tmp_path, abort_offset_m):
    """The mission's own ``grab_abort_offset_m`` (0.08 m since 2026-12-04; 0.15 before): the marker is seen sliding
    0.2 m aside over 0.5 s as GRAB begins from 1 m. With the old 0.15 m the sink goes on, and the gripper closes
    1.23 s into the slide 0.098 m off the object (the water met 0.079 m off). With the mission's limit it gives the
    grab up 0.3 s into the slide, 0.7 m over the water, and picks the object up later, 0.012 m off. (At 0.10 m it
    gave up 1.05 s in and, sinking on for a moment as it turned, touched the water 0.10 m off, the gripper open:
    such a contact, if any, must come after the give-up and within the capture radius.) Judged from the
    simulator's side."""
    params = {} if abort_offset_m == "default" else {"grab_abort_offset_m": abort_offset_m}
    slide_n_m = [0.2 * (k + 1) / 25 for k in range(25)]
    flight, world, left, spell = await fly_with_marker_moved_in_grab(tmp_path, slide_n_m, 1.5, **params)
    first_grab = world.outcome.grabs[0]
    if abort_offset_m == 0.15:
        assert left[0]["reason"] == "grab_settled"
        assert spell["t_s"] < first_grab["t_s"] < spell["end_s"] and first_grab["error_m"] > 0.09
        return
    assert left[0]["reason"] == "grab_gone_off" and left[0]["to"] == "TRACK"
    assert all(not spell["t_s"] <= g["t_s"] <= left[0]["t_s"] + 0.5 for g in world.outcome.grabs)  # gripper open
    in_spell = [c for c in world.outcome.contacts if spell["t_s"] <= c["t_s"] <= spell["end_s"]]
    assert all(c["t_s"] > left[0]["t_s"] and c["error_m"] <= world.scenario.capture_radius_m for c in in_spell)
    assert flight.result.outcome == "picked_up" and world.outcome.caught
    assert world.outcome.grabs[0]["t_s"] > spell["end_s"] and world.outcome.touchdown_error_m < 0.05


@pytest.mark.parametrize("climb_speed_mps", ["default", None])
@pytest.mark.looptime(noop_cycles=2)
async def test_arducopter_giving_a_grab_up_climbs_off_the_water_at_the_climb_speed(tmp_path, climb_speed_mps):
    """ArduCopter gives GRAB up (the marker seen sliding 0.2 m aside) and TRACK climbs back to its height over
    the sea. Its guidance saturates at 1.2 m/s (GUIDED's shaping), and a crest rising 1.3 m/s met a vehicle
    climbing back at 1.16 m/s, 0.26 m off the object (sea state 3, seed 4 run 38). The climb has its own
    saturation, ``guidance.climb_speed_max_mps`` (2 m/s): judged from the simulator's side, the vehicle climbs
    faster than 1.7 m/s within 1.5 s of giving up, against at most 1.25 m/s without it, and picks the object up."""
    settings = load_settings()
    if climb_speed_mps is None:
        guidance = settings.guidance.model_copy(update={"climb_speed_max_mps": None})
        settings = settings.model_copy(update={"guidance": guidance})
    slide_n_m = [0.2 * (k + 1) / 25 for k in range(25)]
    flight, world, left, _ = await fly_with_marker_moved_in_grab(
        tmp_path, slide_n_m, 1.5, profile=Profile.ARDUPILOT, settings=settings
    )
    assert left[0]["reason"] == "grab_gone_off" and left[0]["to"] == "TRACK"
    t0_s = left[0]["t_s"]
    climb_mps = max(-vd for t, _, vd, _ in world.samples if t0_s <= t <= t0_s + 1.5)
    print(f"climbing back: up to {climb_mps:.2f} m/s")
    if climb_speed_mps is None:
        assert climb_mps < 1.25
    else:
        assert climb_mps > 1.7
    assert flight.result.outcome == "picked_up" and world.outcome.caught
    assert all(c["error_m"] <= world.scenario.capture_radius_m for c in world.outcome.contacts)


@pytest.mark.parametrize(("seed", "kind"), [(1, "marker"), (2, "marker"), (3, "marker"), (1, "buoy"), (2, "buoy")])
@pytest.mark.looptime(noop_cycles=2)
async def test_sea_state_2_with_current_and_wind_picks_up_the_object_riding_the_waves(seed, kind):
    """The default scenario (sea state 2, current 0.3 m/s, wind 5 m/s): the object orbits ±0.25 m on the
    waves and heaves; guidance follows it horizontally and holds a height above the *mean* sea. The object is
    the marker, or a plain 0.15 m buoy (fixed from its centre, its size checked as a sphere's)."""
    scenario = PickupScenario(seed=seed, sea_state=2, current_mps=0.3, object_kind=kind)
    settings = load_settings()
    if kind == "buoy":  # the buoy detector, as ``app.main --object buoy`` (it also sets the search's height)
        settings = settings.model_copy(update={"detector": settings.detector.model_copy(update={"kind": "buoy"})})
    vehicle = InProcessVehicle(seed=seed, wind=WindConfig())
    world = PickupWorld(vehicle, scenario, settings)
    runners: list = []
    table = load_mission("pickup")
    flight = await fly_mission(
        vehicle,
        table,
        settings,
        LoopClock(),
        EventLog(None),
        on_start=runners.append,
        sensors=[world.sensors],
    )
    world.model = runners[0].mission
    out = world.outcome
    print(f"seed {seed} {kind}: {flight.result.outcome}, grabs {out.grabs}, {flight.figures['fixes_rejected']}")
    assert flight.result.outcome == "picked_up" and out.caught
    assert all(g["error_m"] <= scenario.capture_radius_m for g in out.grabs)  # never off target on the water:
    assert all(c["error_m"] <= scenario.capture_radius_m for c in out.contacts)  # not even without a grab
    # the gripper closed on the water, not over it (touchdown is judged 0.3 m up: the radar sees no closer)
    assert all(g["height_m"] <= 0.1 and any(c["t_s"] <= g["t_s"] for c in out.contacts) for g in out.grabs)
    assert_never_descends_low_without_a_fresh_fix(world, table.params)


@pytest.mark.parametrize(("echo_beyond_m", "expected"), [(7.5, "ok at 13 m"), (30.0, "failed: ")])
@pytest.mark.looptime(noop_cycles=2)
async def test_radar_calibration_climbs_higher_when_the_sea_is_still_in_range_and_goes_on_without_it(
    echo_beyond_m, expected
):
    """The background capture fails while the sea echoes (here up to 5 + ``echo_beyond_m`` m): CALIBRATE_RADAR
    tries 3 m higher, three heights in all; if every one fails, the mission goes on with the clutter map."""
    scenario = PickupScenario(seed=2, sea_state=0, current_mps=0.1, radar_echo_beyond_range_m=echo_beyond_m)
    flight, world, p = await fly_pickup(scenario, WindConfig.off())
    calibration = flight.figures["radar_calibration"]
    print(calibration, world.calibrated_at_m)
    assert calibration.startswith(expected)
    if expected.startswith("ok"):  # from the vehicle's side: it captured the background 13 m over the sea
        assert world.calibrations == 1 and 12.5 <= world.calibrated_at_m <= 13.6
    else:
        assert world.calibrations == 0 and calibration.count("the sea is in range") == p.calibrate_attempts
    assert flight.result.outcome == "picked_up"  # with or without the map


@pytest.mark.looptime(noop_cycles=2)
async def test_on_ardupilot_it_takes_off_from_the_water_with_nav_takeoff_and_brings_the_object_home():
    """ArduCopter's GUIDED keeps a landed vehicle at ground idle whatever velocity it is sent (and DISARM_DELAY
    runs): after the grab the mission leaves offboard (zero velocity, then BRAKE), takes off with NAV_TAKEOFF and
    takes GUIDED back. Checked from the vehicle's side. With ArduCopter's default vertical limits (WPNAV_ACCEL_Z
    1 m/s², PSC_JERK_Z 5 m/s³; seapick raises them) it sinks on onto the water at the grab."""
    scenario = PickupScenario(seed=1, sea_state=0, current_mps=0.1)
    settings = load_settings()
    ap = settings.guidance.ardupilot.model_copy(update={"autopilot_params": {"PSC_JERK_XY": 20.0}})
    settings = settings.model_copy(update={"guidance": settings.guidance.model_copy(update={"ardupilot": ap})})
    flight, world, _ = await fly_pickup(scenario, WindConfig.off(), profile="ardupilot", settings=settings)
    recs = world.vehicle.records
    print(flight.result.states_visited, world.outcome.grabs)
    assert flight.result.outcome == "picked_up" and world.outcome.caught
    grab_s = next(r["t_s"] for r in recs if r["event"] == "command" and r["command"] == "DO_GRIPPER")
    after = [r for r in recs if r["t_s"] >= grab_s and r["event"] != "setpoint"]
    landed_s = next(r["t_s"] for r in after if r["event"] == "landed_state" and r["landed_state"] == "ON_GROUND")
    brake_s = next(r["t_s"] for r in after if r["event"] == "mode" and r.get("autopilot_mode") == "BRAKE")
    takeoff_s = next(r["t_s"] for r in after if r["event"] == "command" and r["command"] == "NAV_TAKEOFF")
    airborne_s = next(r["t_s"] for r in after if r["event"] == "landed_state" and r["landed_state"] == "IN_AIR")
    assert landed_s < brake_s <= takeoff_s < airborne_s < landed_s + 5.0
    # the setpoints just before BRAKE were zero velocity (leaving offboard on our own account)
    last_sp = [r for r in recs if r["event"] == "setpoint" and r["t_s"] <= brake_s][-1]
    assert max(abs(v) for v in last_sp["vel_ned_mps"]) == 0.0, last_sp
    # it never disarmed on the water: the only disarm is the landing at home
    disarms = [r for r in recs if r["event"] == "armed" and not r["armed"]]
    assert len(disarms) == 1 and disarms[0]["t_s"] > airborne_s + 10.0
    assert flight.result.states_visited[-3:] == ["RETURN", "LAND_HOME", "DONE"]


@pytest.mark.looptime(noop_cycles=2)
async def test_the_search_drifts_with_the_forecast_current_and_finds_an_object_it_would_miss_standing_still():
    """A 0.9 m/s current carries the object ~35 m from where it was reported before the vehicle gets there (and
    farther while it searches): a search standing on the report never sees it; one drifting with the forecast
    current (here 10 % slow and 10° off) finds it and picks it up."""
    # towards the south-east: the object stays well inside the 100 m geofence while the vehicle catches it
    to_rad = math.radians(160.0)
    scenario = PickupScenario(seed=1, sea_state=0, current_mps=0.9, current_to_deg=150.0)
    forecast = (0.81 * math.cos(to_rad), 0.81 * math.sin(to_rad))
    drifting, world, _ = await fly_pickup(scenario, WindConfig.off(), search_drift_ne_mps=forecast)
    print(drifting.result.states_visited, world.outcome.grabs)
    assert drifting.result.outcome == "picked_up" and world.outcome.caught
    standing, world, _ = await fly_pickup(scenario, WindConfig.off())
    print(standing.result)
    assert standing.result.outcome == "failed" and "APPROACH" not in standing.result.states_visited


@pytest.mark.looptime(noop_cycles=2)
async def test_after_the_pickup_time_limit_in_the_air_it_gives_up_and_comes_home():
    """The object is nowhere near where it was reported: the search would go on for its own 400 s; the mission's
    time budget in the air (here 90 s) ends it first, from whatever state it is in, and the vehicle comes home."""
    scenario = PickupScenario(seed=1, sea_state=0, current_mps=0.0, object_start_ne_m=(300.0, -300.0))
    events = EventLog(None)
    states: list[dict] = []
    events.subscribe(["state"], states.append)
    flight, _, _ = await fly_pickup(scenario, WindConfig.off(), events=events, pickup_time_limit_s=90.0)
    print([(r["t_s"], r["to"], r["reason"]) for r in states])
    gave_up = next(r for r in states if r["reason"] == "pickup_time_up")
    airborne_s = next(r["t_s"] for r in states if r["to"] == "TAKEOFF")
    assert gave_up["from"] == "SEARCH" and gave_up["to"] == "RETURN"
    assert 90.0 < gave_up["t_s"] - airborne_s < 91.0
    assert flight.result.outcome == "failed" and flight.result.final_state == "RETURNED_EMPTY"


@pytest.mark.looptime(noop_cycles=2)
async def test_a_missed_object_drifting_out_of_view_during_the_takeoff_from_the_water_is_followed_and_seen():
    """ArduCopter takes 3–4 s to leave the water after a grab; a missed object in a 1 m/s current is metres away
    by then, outside the 3 m view over the grab point. VERIFY looks where the object's drift takes it (and only
    judges "in the gripper" once it is over that point), so the miss is seen, regrabbed and caught, never
    reported as a pickup while the object floats on."""
    # south-east: the object stays inside the 100 m fence while all this goes on
    scenario = PickupScenario(seed=1, sea_state=0, current_mps=1.0, current_to_deg=150.0, fail_first_grabs=1)
    drift = (math.cos(math.radians(150.0)), math.sin(math.radians(150.0)))
    flight, world, _ = await fly_pickup(scenario, WindConfig.off(), profile="ardupilot", search_drift_ne_mps=drift)
    visited, grabs = flight.result.states_visited, world.outcome.grabs
    print(visited, grabs, flight.figures["retries"])
    assert [g["caught"] for g in grabs] == [False, True]  # the first grab slipped: the object stayed on the sea
    i = visited.index("VERIFY")
    assert visited[i : i + 2] == ["VERIFY", "REGRAB"]  # seen from above, not taken as caught
    assert flight.result.outcome == "picked_up" and world.outcome.caught


@pytest.mark.looptime(noop_cycles=2)
@pytest.mark.parametrize("profile", ["px4", "ardupilot"])
async def test_a_resume_that_comes_while_hold_is_still_leaving_offboard_takes_offboard_again(profile):
    """A ground station's hold 1 s into TRACK leaves offboard (zero velocity for 0.5 s, then HOLD); a resume 0.2 s
    later enters TRACK while that is still going on. The state that resumes must take offboard again once the HOLD
    has gone out: checked from the vehicle's side, it flies offboard again and follows the object to the pickup
    (eval run 51: the same race after a takeoff from the water left the vehicle in BRAKE on the sea for 235 s).
    On PX4 the filter has converged by then: the hold comes in DESCEND, and the resumed TRACK goes on to DESCEND at
    once, cancelling TRACK's entry while it still waited for HOLD's — DESCEND must wait for the HOLD too (it did not
    before ``VehicleBoundary.leave_settled``: the vehicle stayed in HOLD)."""
    settings = load_settings()
    scenario = PickupScenario(seed=1, sea_state=0, current_mps=0.1)
    calibrated = SIM_PROFILES[profile]
    vehicle = InProcessVehicle(
        seed=1, wind=WindConfig.off(), profile=calibrated.autopilot, vehicle_params=calibrated.airframe
    )
    world = PickupWorld(vehicle, scenario, settings)
    runners, seen = [], {}

    async def hold_then_resume_at_once():
        while not runners or runners[0].state != "TRACK":  # noqa: ASYNC110
            await asyncio.sleep(0.02)  # polls the mission's state: nothing to wait on
        await asyncio.sleep(1.0)
        assert runners[0].request("hold") is None
        await asyncio.sleep(0.2)
        seen["resume_s"] = asyncio.get_running_loop().time()
        assert runners[0].request("resume") is None
        await asyncio.sleep(4.0)
        seen["mode"] = vehicle.truth().flight_mode

    watcher = asyncio.create_task(hold_then_resume_at_once())
    flight = await fly_mission(
        vehicle, load_mission("pickup"), settings, LoopClock(), EventLog(None),
        on_start=runners.append, sensors=[world.sensors],
    )  # fmt: skip
    watcher.cancel()
    print(seen, flight.result.states_visited)
    assert seen["mode"] is FlightMode.OFFBOARD  # 4 s after the resume (ArduPilot: GUIDED)
    modes = [r["mode"] for r in vehicle.records if r["event"] == "mode" and 0 <= r["t_s"] - seen["resume_s"] <= 4.0]
    assert modes == ["HOLD", "OFFBOARD"], modes  # the hold's HOLD went out after the resume, then offboard again
    assert flight.result.outcome == "picked_up" and world.outcome.caught


@pytest.mark.looptime(noop_cycles=2)
async def test_an_object_lost_again_after_search_retries_searches_is_given_up_and_the_vehicle_comes_home():
    """The camera goes blind every time the vehicle is over the object (TRACK) and sees again once it searches:
    two searches around the last estimate (``search_retries`` 2), and the third loss goes home instead of
    searching — as PX4's PLD_MAX_SRCH and ArduPilot's PLND_RET_MAX bound precision landing's retries."""
    scenario = PickupScenario(seed=1, sea_state=0, current_mps=0.1)
    events = EventLog(None)
    states: list[dict] = []
    events.subscribe(["state"], states.append)
    world_box: list[PickupWorld] = []

    async def blind_while_tracking() -> None:
        while True:
            state = states[-1]["to"] if states else ""
            if world_box:
                world_box[0].camera_blind = state == "TRACK"
            await asyncio.sleep(0.05)  # polls the mission's state: nothing to wait on

    watcher = asyncio.create_task(blind_while_tracking())
    settings = load_settings()
    vehicle = InProcessVehicle(seed=scenario.seed, wind=WindConfig.off())
    world = PickupWorld(vehicle, scenario, settings)
    world_box.append(world)
    table = load_mission("pickup")
    table = table.model_copy(update={"params": table.params.model_copy(update={"search_retries": 2})})
    flight = await fly_mission(vehicle, table, settings, LoopClock(), events, sensors=[world.sensors])
    watcher.cancel()
    moves = [(round(r["t_s"], 1), r["from"], r["to"], r["reason"]) for r in states]
    print(moves, flight.figures.get("searches_after_loss"))
    lost = [m for m in moves if m[3] in ("target_lost", "target_lost_finally") and m[1] == "TRACK"]
    assert [m[2:] for m in lost] == [("SEARCH", "target_lost")] * 2 + [("RETURN", "target_lost_finally")]
    assert flight.figures["searches_after_loss"] == 2
    assert flight.result.outcome == "failed" and flight.result.final_state == "RETURNED_EMPTY"
    assert world.outcome.grabs == []  # never went down onto it
    truth = vehicle.truth()
    assert not truth.armed and math.hypot(truth.pos_ned_m[0], truth.pos_ned_m[1]) < 2.0  # landed at home


async def fly_pickup_watching_attitude(**params):
    """The default scenario's pickup (marker) in 8 m/s of wind from the north, the vehicle's truth at every camera
    frame and the mission's states."""
    events = EventLog(None)
    states: list[dict] = []
    events.subscribe({"state"}, states.append)
    scenario = PickupScenario(seed=1, sea_state=2, current_mps=0.3)
    settings = load_settings()
    vehicle = InProcessVehicle(seed=1, wind=WindConfig(mean_mps=8.0, from_deg=0.0, gust_sigma_mps=0.8))
    world = PickupWorld(vehicle, scenario, settings)
    truth: list[tuple[float, float, float, float]] = []
    world.frame_observers.append(lambda t_s, s, _o: truth.append((t_s, s.roll_rad, s.pitch_rad, s.yaw_rad)))
    table = load_mission("pickup")
    table = table.model_copy(update={"params": table.params.model_copy(update=params)})
    flight = await fly_mission(vehicle, table, settings, LoopClock(), events, sensors=[world.sensors])
    spans = {}
    for a, b in itertools.pairwise(states):
        spans.setdefault(a["to"], (a["t_s"], b["t_s"]))
    t0, t1 = spans["DESCEND"]
    descend = np.array([x[1:] for x in truth if t0 <= x[0] < t1])
    return flight, world, descend, vehicle.records


@pytest.mark.looptime(noop_cycles=2)
async def test_in_wind_it_turns_so_the_lean_lies_along_the_pictures_wider_side():
    """8 m/s from the north, the vehicle heading north: it leans into the wind nose-down, so the object under it
    sits off the picture's centre along its narrow side (960 px, ±25.6°). With ``lean_yaw_min_tilt_deg`` set (5°) it
    turns a quarter round and the same lean becomes a roll, along the wide side (±32.6°).
    Judged from the simulator's truth of the vehicle in DESCEND and its log of the setpoints it was sent."""
    flight, world, descend, records = await fly_pickup_watching_attitude(lean_yaw_min_tilt_deg=5.0)
    roll, pitch, yaw = np.degrees(descend[:, 0]), np.degrees(descend[:, 1]), np.degrees(descend[:, 2])
    print(f"turned: mean roll {roll.mean():.1f}°, pitch {pitch.mean():.1f}°, yaw {np.median(yaw):.0f}°, "
          f"{flight.result.outcome}, grabs {world.outcome.grabs}")  # fmt: skip
    assert flight.result.outcome == "picked_up" and world.outcome.caught
    assert abs(roll.mean()) > 5.0 and abs(pitch.mean()) < abs(roll.mean()) / 3.0  # the lean is a roll
    assert 80.0 < abs(np.median(yaw)) < 100.0  # side on to the wind
    assert all(c["error_m"] <= 0.25 for c in world.outcome.contacts)
    asked = [r["yaw_rad"] for r in records if r["event"] == "setpoint" and r.get("yaw_rad") is not None]
    assert any(abs(abs(math.degrees(y)) - 90.0) < 10.0 for y in asked)


@pytest.mark.looptime(noop_cycles=2)
async def test_unset_the_heading_is_held_and_the_lean_stays_along_the_nose():
    """Unset (pickup.yaml's default) the heading is held."""
    flight, world, descend, records = await fly_pickup_watching_attitude()
    roll, pitch, yaw = np.degrees(descend[:, 0]), np.degrees(descend[:, 1]), np.degrees(descend[:, 2])
    print(f"held: mean roll {roll.mean():.1f}°, pitch {pitch.mean():.1f}°, yaw {np.median(yaw):.0f}°, "
          f"{flight.result.outcome}, grabs {world.outcome.grabs}")  # fmt: skip
    assert abs(np.median(yaw)) < 5.0 and np.ptp(yaw) < 5.0  # the heading held (north)
    assert abs(pitch.mean()) > 5.0 and abs(roll.mean()) < abs(pitch.mean()) / 3.0  # the lean along the nose
    asked = {round(r["yaw_rad"], 6) for r in records if r["event"] == "setpoint" and r.get("yaw_rad") is not None}
    assert all(abs(y) < math.radians(5.0) for y in asked)
