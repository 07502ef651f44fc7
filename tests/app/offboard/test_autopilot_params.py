"""Parameters the settings set on the autopilot before arming (``guidance.<autopilot>.autopilot_params``):
ArduPilot's PSC_JERK_XY, PSC_JERK_Z and WPNAV_ACCEL_Z, over MAVLink and in process, as the vehicle sees them."""

from __future__ import annotations

import asyncio
import json

import pytest

from app.clock import LoopClock
from app.errors import VehicleError
from app.eventlog import EventLog
from app.flight import set_autopilot_params
from app.settings import Settings, load_settings
from sim.autopilot_modes import Profile
from sim.inproc import InProcessVehicle
from sim.wind import WindConfig
from tests.sim.conftest import app_vehicle_on_sim, eventually

LOOPTIME = pytest.mark.looptime(noop_cycles=2)


def with_params(params: dict[str, float]) -> Settings:
    s = load_settings()
    ap = s.guidance.ardupilot.model_copy(update={"autopilot_params": params})
    return s.model_copy(update={"guidance": s.guidance.model_copy(update={"ardupilot": ap})})


def param_records(vehicle: InProcessVehicle) -> list[tuple[str, float]]:
    return [(r["name"], r["value"]) for r in vehicle.records if r["event"] == "param"]


@LOOPTIME
async def test_ardupilot_gets_its_shaping_limits_and_flies_with_them_px4_gets_nothing():
    events = EventLog(None)
    logged: list[dict[str, object]] = []
    events.subscribe({"run"}, logged.append)
    ap = InProcessVehicle(profile=Profile.ARDUPILOT, wind=WindConfig.off())
    await ap.wait_ready(10.0)
    assert ap.stack.dyn.shaping_xy == (5.0, 2.5)  # ArduCopter's defaults: PSC_JERK_XY 5, WPNAV_ACCEL 250 cm/s²
    assert ap.stack.dyn.shaping_z == (5.0, 1.0)  # PSC_JERK_Z 5, WPNAV_ACCEL_Z 100 cm/s²
    await set_autopilot_params(ap, load_settings(), LoopClock(), events)
    await asyncio.sleep(0.01)
    ap.truth()  # the physics brought up to now: the next tick took it
    wanted = [("PSC_JERK_XY", 20.0), ("PSC_JERK_Z", 50.0), ("WPNAV_ACCEL_Z", 500.0)]
    assert param_records(ap) == wanted  # the vehicle's own log
    assert ap.stack.params.get("PSC_JERK_XY") == 20.0 and ap.stack.dyn.shaping_xy == (20.0, 2.5)
    assert ap.stack.dyn.shaping_z == (50.0, 5.0)
    assert [(r["name"], r["value"]) for r in logged if r.get("event") == "param_set"] == wanted

    px4 = InProcessVehicle(profile=Profile.PX4, wind=WindConfig.off())
    await px4.wait_ready(10.0)
    await set_autopilot_params(px4, load_settings(), LoopClock(), EventLog(None))
    assert param_records(px4) == [] and px4.stack.dyn.shaping_xy is None


@LOOPTIME
async def test_an_unknown_parameter_is_refused_and_nothing_is_set():
    vehicle = InProcessVehicle(profile=Profile.ARDUPILOT, wind=WindConfig.off())
    await vehicle.wait_ready(10.0)
    with pytest.raises(VehicleError) as e:
        await set_autopilot_params(vehicle, with_params({"PSC_JERK_XZ": 20.0}), LoopClock(), EventLog(None))
    assert (e.value.command, e.value.result) == ("set_param", "DOES_NOT_EXIST")
    assert param_records(vehicle) == [] and vehicle.stack.params.get("PSC_JERK_XY") == 5.0


async def velocity_after(jerk_mps3: float, after_s: float) -> float:
    """North velocity of the simulated ArduCopter ``after_s`` into a 0 → 1 m/s north setpoint step in GUIDED."""
    vehicle = InProcessVehicle(profile=Profile.ARDUPILOT, wind=WindConfig.off(), params={"PSC_JERK_XY": jerk_mps3})
    await vehicle.wait_ready(10.0)
    await vehicle.arm()
    await vehicle.takeoff(3.0)
    await asyncio.sleep(8.0)
    await vehicle.start_offboard(0.0)
    await asyncio.sleep(1.0)
    t_end = asyncio.get_running_loop().time() + after_s
    while asyncio.get_running_loop().time() < t_end:
        await vehicle.set_velocity_ned((1.0, 0.0, 0.0), 0.0)
        await asyncio.sleep(0.02)
    return vehicle.truth().vel_ned_mps[0]


@LOOPTIME
async def test_a_higher_jerk_limit_answers_a_velocity_step_sooner():
    slow, fast = await velocity_after(5.0, 0.6), await velocity_after(20.0, 0.6)
    print(f"0.6 s into a 1 m/s step: {slow:.2f} m/s with PSC_JERK_XY 5, {fast:.2f} m/s with 20")
    assert fast > slow + 0.15


async def climb_after(params: dict[str, float], after_s: float) -> tuple[float, float]:
    """Climb rate (m/s, up) of the simulated ArduCopter ``after_s`` into a 0 → 1.5 m/s climb setpoint step in
    GUIDED while descending at 0.5 m/s (a vehicle giving up a descent to the sea), and how far it sank first (m)."""
    vehicle = InProcessVehicle(profile=Profile.ARDUPILOT, wind=WindConfig.off(), params=params)
    await vehicle.wait_ready(10.0)
    await vehicle.arm()
    await vehicle.takeoff(5.0)
    await asyncio.sleep(8.0)
    await vehicle.start_offboard(0.0)
    for _ in range(150):  # 3 s down at 0.5 m/s
        await vehicle.set_velocity_ned((0.0, 0.0, 0.5), 0.0)
        await asyncio.sleep(0.02)
    down_at_step_m = deepest_m = vehicle.truth().pos_ned_m[2]
    t_end = asyncio.get_running_loop().time() + after_s
    while asyncio.get_running_loop().time() < t_end:
        await vehicle.set_velocity_ned((0.0, 0.0, -1.5), 0.0)
        await asyncio.sleep(0.02)
        deepest_m = max(deepest_m, vehicle.truth().pos_ned_m[2])
    return -vehicle.truth().vel_ned_mps[2], deepest_m - down_at_step_m


@LOOPTIME
async def test_higher_vertical_limits_turn_a_descent_into_a_climb_sooner_and_sink_less():
    default = await climb_after({}, 0.8)
    agile = await climb_after({"PSC_JERK_Z": 50.0, "WPNAV_ACCEL_Z": 500.0}, 0.8)
    print(
        f"0.8 s into a climb from 0.5 m/s down: {default[0]:.2f} m/s up, sank {default[1]:.3f} m with ArduCopter's"
        f" defaults (5 m/s³, 100 cm/s²); {agile[0]:.2f} m/s up, sank {agile[1]:.3f} m with 50 m/s³, 500 cm/s²"
    )
    assert default[0] < 0.3 and default[1] > 0.1  # 1 m/s²: still not climbing much, sank on for a decimetre
    assert agile[0] > default[0] + 0.8 and agile[1] < default[1] / 2


async def test_over_mavlink_mavsdk_sets_it_and_the_simulated_ardupilot_flies_with_it(tmp_path):
    log = tmp_path / "sim_state.jsonl"
    settings, clock, events = load_settings(), LoopClock(), EventLog(None)
    config = {"profile": Profile.ARDUPILOT, "state_log": str(log), "wind": WindConfig.off(), "seed": 1}
    async with app_vehicle_on_sim(settings, clock, events, **config) as (sim, vehicle):
        assert sim.stack.dyn.shaping_xy == (5.0, 2.5)
        await set_autopilot_params(vehicle, settings, clock, events)
        await eventually(lambda: (sim.stack.dyn.shaping_xy, sim.stack.dyn.shaping_z) == ((20.0, 2.5), (50.0, 5.0)), 2.0)
    params = [(r["name"], r["value"]) for r in map(json.loads, log.read_text().splitlines()) if r["event"] == "param"]
    assert params == [("PSC_JERK_XY", 20.0), ("PSC_JERK_Z", 50.0), ("WPNAV_ACCEL_Z", 500.0)]
