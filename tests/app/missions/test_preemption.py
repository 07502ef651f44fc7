"""The defects of the flight-safety review (issue 9), each checked from the vehicle's side: on what the
in-process simulated autopilot received (``vehicle.records``), in virtual time, on the real ``fly_mission``.
"""

from __future__ import annotations

import asyncio
import math
import os
import signal

import pytest

from app.clock import LoopClock
from app.errors import VehicleError
from app.eventlog import EventLog
from app.flight import fly_mission
from app.messages import FlightMode
from app.missions.table import load_mission
from app.settings import Settings
from sim.autopilot_modes import Profile
from sim.faulty_vehicle import FaultyVehicle, stall_loop
from sim.wind import WindConfig

LOOPTIME = pytest.mark.looptime(noop_cycles=2)


def commands(vehicle, after_s=-1.0, source="link"):
    return [r for r in vehicle.records if r["event"] == "command" and r["source"] == source and r["t_s"] > after_s]


def setpoints(vehicle, after_s=-1.0):
    return [r for r in vehicle.records if r["event"] == "setpoint" and r["t_s"] > after_s]


def is_zero(sp):
    return all(v == 0.0 for v in sp["vel_ned_mps"])


def mode_commands(vehicle, after_s=-1.0):
    return [r for r in commands(vehicle, after_s) if r["command"] == "DO_SET_MODE"]


async def wait_for(pred, clock, limit_s=120.0):
    t0 = clock.now_s()
    while not pred():
        assert clock.now_s() - t0 < limit_s, "condition never came"
        await clock.sleep(0.01)
    return clock.now_s()


def start(vehicle, mission="circle", settings=None, table=None):
    table = table or load_mission(mission)
    return asyncio.create_task(fly_mission(vehicle, table, settings or Settings(), LoopClock(), EventLog(None)))


def first_command(vehicle, name):
    return next(r for r in commands(vehicle) if r["command"] == name)


# ---- 1. commands after an abort or a pilot takeover -------------------------------------------------


@LOOPTIME
async def test_sigint_during_a_slow_arm_sends_no_takeoff():
    vehicle = FaultyVehicle(seed=1)
    vehicle.slow_s["arm"] = 2.0
    clock = LoopClock()
    task = start(vehicle)
    t_arm = await wait_for(lambda: vehicle.stack.t_s > 0 and _entered_takeoff(vehicle), clock)
    await clock.sleep(1.6)
    os.kill(os.getpid(), signal.SIGINT)
    flight = await task
    t_sig = t_arm + 1.6
    assert flight.result.outcome == "aborted" and "SIGINT" in flight.result.reason
    late = [r for r in commands(vehicle, t_sig) if r["command"] in ("NAV_TAKEOFF", "COMPONENT_ARM_DISARM")]
    assert late == [], late
    assert not vehicle.truth().armed


def _entered_takeoff(vehicle):
    # The slow arm started: the vehicle has not answered anything yet but the mission left PREFLIGHT.
    return vehicle.stack.started and vehicle.slow_s == {}


@LOOPTIME
async def test_pilot_switch_during_a_slow_arm_is_never_overridden():
    vehicle = FaultyVehicle(seed=1)
    vehicle.slow_s["arm"] = 2.0
    clock = LoopClock()
    task = start(vehicle)
    await wait_for(lambda: _entered_takeoff(vehicle), clock)
    await clock.sleep(1.7)
    vehicle.pilot_set_mode(FlightMode.POSCTL)
    t_switch = clock.now_s()
    await clock.sleep(10.0)
    assert vehicle.truth().flight_mode is FlightMode.POSCTL
    assert commands(vehicle, t_switch) == []  # no arm landing late, no takeoff, no HOLD
    assert all(is_zero(s) for s in setpoints(vehicle, t_switch))
    vehicle.pilot_set_mode(FlightMode.LAND)
    flight = await task
    assert flight.result.final_state in ("PILOT_LANDED", "PILOT_KEPT_CONTROL"), flight.result


# ---- 2. every exit from offboard sends zero velocity, then HOLD -------------------------------------


def assert_zero_then_hold(vehicle, after_s, zero_s=0.5, until_s=float("inf")):
    """Zero velocity for ``zero_s``, then HOLD, and nothing moving sent after it (up to ``until_s``)."""
    holds = [r for r in mode_commands(vehicle, after_s) if r["mode"] == FlightMode.HOLD.value]
    assert holds, "no HOLD command after leaving offboard"
    t_hold = holds[0]["t_s"]
    before = [s for s in setpoints(vehicle, after_s) if s["t_s"] <= t_hold]
    assert before and is_zero(before[-1]), before[-3:]
    window = [s for s in before if s["t_s"] >= t_hold - zero_s + 0.05]
    assert len(window) >= 5 and all(is_zero(s) for s in window), window
    after = [s for s in setpoints(vehicle, t_hold) if s["t_s"] < until_s]
    assert all(is_zero(s) for s in after), "non-zero setpoint after HOLD"
    return t_hold


async def in_track(vehicle, clock, s=5.0):
    await wait_for(lambda: vehicle.truth().flight_mode is FlightMode.OFFBOARD, clock)
    await clock.sleep(s)
    assert not is_zero(setpoints(vehicle)[-1]), "should be flying the circle"
    return clock.now_s()


@LOOPTIME
async def test_ctrl_c_in_track_sends_zero_velocity_then_hold():
    vehicle = FaultyVehicle(seed=1)
    clock = LoopClock()
    task = start(vehicle)
    t_sig = await in_track(vehicle, clock)
    os.kill(os.getpid(), signal.SIGINT)
    flight = await task
    assert flight.result.outcome == "aborted"
    assert_zero_then_hold(vehicle, t_sig)
    assert vehicle.truth().flight_mode is FlightMode.HOLD


TRACK_THEN_FAILED = """
mission: track_then_failed
initial: PREFLIGHT
states:
  PREFLIGHT: {transitions: [{when: vehicle_ready, to: TAKEOFF}], timeout_s: 30, on_timeout: FAILED}
  TAKEOFF:
    control: autopilot
    entry: [arm, takeoff]
    transitions:
      - {when: abort_requested, to: ABORT}
      - {when: link_lost, to: ABORT}
      - {when: position_lost, to: ABORT}
      - {when: setpoints_failing, to: ABORT}
      - {when: at_takeoff_altitude, to: TRACK}
    timeout_s: 45
    on_timeout: ABORT
  TRACK:
    control: offboard
    entry: [start_offboard, start_circle]
    transitions:
      - {when: abort_requested, to: ABORT}
      - {when: link_lost, to: ABORT}
      - {when: position_lost, to: ABORT}
      - {when: setpoints_failing, to: ABORT}
      - {when: circle_laps_done, to: DONE}
    timeout_s: 8
    on_timeout: FAILED
  DONE: {terminal: completed}
  MANUAL: {manual: true, transitions: [{when: disarmed, to: PILOT}], resume_default: TRACK, timeout_s: 600,
           on_timeout: PILOT}
  ABORT: {abort: true, entry: [stop_and_hold], terminal: aborted}
  FAILED: {terminal: failed}
  PILOT: {terminal: pilot}
"""


@LOOPTIME
async def test_track_to_a_state_that_commands_nothing_still_leaves_offboard(tmp_path):
    (tmp_path / "track_then_failed.yaml").write_text(TRACK_THEN_FAILED)
    vehicle = FaultyVehicle(seed=1)
    clock = LoopClock()
    task = start(vehicle, table=load_mission(str(tmp_path / "track_then_failed.yaml")))
    t_track = await in_track(vehicle, clock, 1.0)
    flight = await task
    assert flight.result.outcome == "failed"
    assert_zero_then_hold(vehicle, t_track)
    await clock.sleep(3.0)
    assert vehicle.truth().flight_mode is FlightMode.HOLD


# ---- 3. a stalled event loop ------------------------------------------------------------------------


@LOOPTIME
async def test_a_one_second_loop_stall_zeroes_the_resent_setpoint_within_the_watchdog_timeout():
    vehicle = FaultyVehicle(seed=1)
    clock = LoopClock()
    task = start(vehicle)
    await in_track(vehicle, clock)
    t_stall = clock.now_s()
    stall_loop(1.0)
    await clock.sleep(0.5)
    during = [s for s in setpoints(vehicle, t_stall) if s["t_s"] < t_stall + 1.0 - 1e-6]  # the app is back at +1 s
    moving = [s for s in during if not is_zero(s)]
    zeros = [s for s in during if is_zero(s)]
    assert zeros and zeros[0]["origin"] == "watchdog", during[:8]
    watchdog_after_s = zeros[0]["t_s"] - t_stall
    print(f"watchdog zeroed the re-sent setpoint {watchdog_after_s:.3f} s into the stall (virtual time)")
    assert watchdog_after_s <= Settings().guidance.watchdog_timeout_s + 0.05 + 1e-6
    assert all(s["t_s"] < zeros[0]["t_s"] for s in moving)  # nothing non-zero after the watchdog until the app is back
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task


# ---- 4. link health ---------------------------------------------------------------------------------


@LOOPTIME
@pytest.mark.parametrize("fault", ["lose_link", "heartbeat_lost"])
async def test_a_lost_link_in_takeoff_aborts_within_seconds_not_at_the_state_timeout(fault):
    vehicle = FaultyVehicle(seed=1)
    clock = LoopClock()
    task = start(vehicle)
    await wait_for(lambda: vehicle.truth().flight_mode is FlightMode.TAKEOFF, clock)
    await clock.sleep(1.0)
    t_fault = clock.now_s()
    if fault == "lose_link":
        vehicle.lose_link()
    else:
        vehicle.heartbeat_lost = True
    flight = await task
    took_s = clock.now_s() - t_fault
    assert flight.result.outcome == "aborted"
    assert flight.result.reason in ("link_lost", "position_lost")
    print(f"{fault}: aborted after {took_s:.2f} s ({flight.result.reason})")
    assert took_s < 3.0 + 1.6 + 1.0  # link_lost_s + a command timeout + margin; TAKEOFF's timeout is 45 s


class FailingSends(FaultyVehicle):
    fail = False

    async def set_velocity_ned(self, vel_ned_mps, yaw_rad):
        if self.fail:
            raise VehicleError("set_velocity_ned", "TIMEOUT", "executor")
        await super().set_velocity_ned(vel_ned_mps, yaw_rad)


@LOOPTIME
async def test_repeated_setpoint_send_failures_abort():
    vehicle = FailingSends(seed=1)
    clock = LoopClock()
    task = start(vehicle)
    await in_track(vehicle, clock)
    vehicle.fail = True
    flight = await task
    assert flight.result.outcome == "aborted" and flight.result.reason == "setpoints_failing"
    assert flight.safety["setpoint_send_failures"] >= 10


# ---- 5. an autopilot failsafe before our mode is confirmed ------------------------------------------


@LOOPTIME
@pytest.mark.parametrize("profile", [Profile.PX4, Profile.ARDUPILOT])
async def test_rtl_failsafe_right_after_our_offboard_command_is_a_takeover_not_overridden(profile):
    vehicle = FaultyVehicle(seed=1, profile=profile)
    vehicle.after["start_offboard"] = lambda: vehicle.autopilot_failsafe(FlightMode.RETURN_TO_LAUNCH)
    flight = await start(vehicle)
    switch = next(r for r in vehicle.records if r["event"] == "mode" and r["reason"] == "failsafe")
    assert flight.result.outcome == "pilot", flight.result
    assert "MANUAL" in flight.result.states_visited and "ABORT" not in flight.result.states_visited
    assert commands(vehicle, switch["t_s"]) == []
    assert all(is_zero(s) for s in setpoints(vehicle, switch["t_s"]))
    assert not vehicle.truth().armed  # RTL brought it home and landed


# ---- 6. a second Ctrl-C during ABORT's stop ---------------------------------------------------------


@LOOPTIME
async def test_second_ctrl_c_during_the_stop_does_not_cut_it_short():
    vehicle = FaultyVehicle(seed=1)
    clock = LoopClock()
    task = start(vehicle)
    t_sig = await in_track(vehicle, clock)
    os.kill(os.getpid(), signal.SIGINT)
    await clock.sleep(0.1)
    os.kill(os.getpid(), signal.SIGINT)
    with pytest.raises(asyncio.CancelledError):
        await task
    assert_zero_then_hold(vehicle, t_sig)
    assert vehicle.truth().flight_mode is FlightMode.HOLD


# ---- 7. non-finite yaw, the envelope at the boundary ------------------------------------------------


@LOOPTIME
async def test_nan_attitude_never_reaches_the_vehicle_as_a_setpoint():
    vehicle = FaultyVehicle(seed=1)
    clock = LoopClock()
    task = start(vehicle)
    await wait_for(lambda: -vehicle.truth().pos_ned_m[2] > 4.0, clock)
    vehicle.nan_streams = {"attitude"}
    vehicle.nan_until_s = clock.now_s() + 2.5  # NaN attitude as offboard starts (shorter than link_lost_s)
    await wait_for(lambda: vehicle.truth().flight_mode is FlightMode.OFFBOARD, clock)
    assert clock.now_s() < vehicle.nan_until_s - 0.5
    flight = await task
    sps = setpoints(vehicle)
    assert flight.result.outcome == "completed", flight.result
    assert len(sps) > 1000 and all(math.isfinite(x) for s in sps for x in (*s["vel_ned_mps"], s["yaw_rad"]))
    assert flight.safety["non_finite_samples"] > 20
    assert flight.result.outcome == "completed"


@LOOPTIME
async def test_every_setpoint_passes_the_envelope_at_the_boundary():
    from app.flight import build_flight

    vehicle = FaultyVehicle(seed=1, wind=WindConfig.off())
    settings, clock, events = Settings(), LoopClock(), EventLog(None)
    boundary, _, _ = build_flight(vehicle, load_mission("circle"), settings, clock, events)
    await vehicle.wait_ready(10.0)
    await vehicle.arm()
    await vehicle.takeoff(5.0)
    await clock.sleep(15.0)
    boundary.flying = True
    await boundary.start_offboard()
    limit = settings.envelope.max_horizontal_speed_mps
    got = await boundary.send_velocity((30.0, 0.0, 0.0), math.nan)
    assert got is not None and math.isclose(got.vel_ned_mps[0], limit) and "non_finite_yaw" in got.limits
    got = await boundary.send_velocity((math.nan, 0.0, 0.0), 0.0)
    last = setpoints(vehicle)[-1]
    assert math.isfinite(last["yaw_rad"]) and all(math.isfinite(v) for v in last["vel_ned_mps"]), last
    assert abs(setpoints(vehicle)[-2]["vel_ned_mps"][0] - limit) < 1e-9
    await boundary.release("test")


# ---- 8. holding with no target keeps a position -----------------------------------------------------


class LostTarget:
    name = "lost"

    def target_at(self, t_s):
        return None

    def observe(self, sample):
        pass


@LOOPTIME
async def test_losing_the_target_holds_the_position_where_it_went_missing():
    """Held where it went missing, in the autopilot's frame: the simulator's truth plus its estimator's position
    error. (The truth alone also wanders with the GNSS estimate, which nobody on board can see: 0.07–0.39 m over
    these 20 s, depending on the estimator's random draws.)"""
    vehicle = FaultyVehicle(seed=3)  # default wind: 5 m/s with gusts
    clock = LoopClock()
    runners = []
    table = load_mission("circle")
    task = asyncio.create_task(
        fly_mission(vehicle, table, Settings(), clock, EventLog(None), on_start=runners.append)
    )  # fmt: skip
    await in_track(vehicle, clock, 12.0)
    runners[0].setpoints.engage(LostTarget())  # the estimate is gone

    def held_ne():
        """Where the autopilot has the vehicle: the truth with the estimator's error (sim.estimator)."""
        p, e = vehicle.truth().pos_ned_m, vehicle.stack.dyn.estimator.pos_err_m
        return p[0] + e[0], p[1] + e[1], p[0], p[1]

    n0, e0, tn0, te0 = held_ne()
    worst = 0.0
    for _ in range(200):  # 20 s
        await clock.sleep(0.1)
        n, e, tn, te = held_ne()
        worst = max(worst, math.hypot(n - n0, e - e0))
    final = math.hypot(n - n0, e - e0)
    print(f"no target for 20 s in wind: worst {worst:.2f} m, final {final:.2f} m from where it went missing "
          f"(the truth: {math.hypot(tn - tn0, te - te0):.2f} m)")  # fmt: skip
    assert final < 0.3 and worst < 1.0
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task


class BuggyTarget:
    name = "buggy"

    def target_at(self, t_s):
        raise ZeroDivisionError("a bug in the guidance code")

    def observe(self, sample):
        pass


@LOOPTIME
async def test_an_exception_in_track_still_leaves_offboard_with_zero_velocity_then_hold():
    vehicle = FaultyVehicle(seed=1)
    clock = LoopClock()
    runners = []
    task = asyncio.create_task(
        fly_mission(vehicle, load_mission("circle"), Settings(), clock, EventLog(None), on_start=runners.append)
    )
    t_bug = await in_track(vehicle, clock)
    runners[0].setpoints.engage(BuggyTarget())
    with pytest.raises(ExceptionGroup) as e:
        await task
    assert e.group_contains(ZeroDivisionError)
    assert_zero_then_hold(vehicle, t_bug)
    assert vehicle.truth().flight_mode is FlightMode.HOLD
