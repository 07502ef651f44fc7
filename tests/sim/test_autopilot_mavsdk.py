"""The MAVLink endpoint against a real MAVSDK 4 client over loopback UDP (real time, seconds each)."""

from __future__ import annotations

import asyncio
import math

import pytest
from mavsdk.asyncio import Autopilot as MavAutopilot
from mavsdk.asyncio import Vehicle as MavVehicle
from mavsdk.asyncio.plugins.offboard import VelocityNedYaw
from mavsdk.asyncio.plugins.telemetry import FlightMode, LandedState

from sim import pilot
from sim.autopilot_modes import DEFAULT_ORIGIN, Mode, Profile
from sim.wind import WindConfig
from tests.sim.conftest import Connected, eventually, first, mavsdk_on_sim


async def armable(c: Connected) -> None:
    await first(c.telemetry.subscribe_health(), lambda h: h.is_armable and h.is_home_position_ok, 10.0)


async def climb_to(c: Connected, height_m: float) -> None:
    await first(c.telemetry.subscribe_position_velocity_ned(), lambda pv: -pv.position.down_m > height_m, 15.0)


async def mode_is(c: Connected, mode: FlightMode, timeout_s: float = 3.0) -> None:
    async def check() -> bool:
        return bool(await c.telemetry.flight_mode() == mode)

    await eventually(check, timeout_s)


async def test_px4_discovery_health_home_and_params() -> None:
    async with mavsdk_on_sim(wind=WindConfig.off()) as c:
        assert await c.system.autopilot_type() == MavAutopilot.PX4
        assert await c.system.vehicle_type() == MavVehicle.MULTICOPTER
        await armable(c)
        health = await c.telemetry.health()
        assert health.is_local_position_ok and health.is_global_position_ok
        home = await c.telemetry.home()  # cached from the HOME_POSITION that made home ok
        assert home.latitude_deg == pytest.approx(DEFAULT_ORIGIN.lat_deg, abs=1e-6)
        assert home.absolute_altitude_m == pytest.approx(DEFAULT_ORIGIN.alt_m, abs=0.01)
        assert await c.action.get_takeoff_altitude() == pytest.approx(2.5)
        await c.action.set_takeoff_altitude(4.0)
        assert await c.action.get_takeoff_altitude() == pytest.approx(4.0)
        assert await c.param.get_param_int("SYS_AUTOSTART") == 10015  # bytewise INT32
        assert await c.telemetry.flight_mode() == FlightMode.HOLD
        assert await c.telemetry.landed_state() == LandedState.ON_GROUND


async def test_px4_flight_offboard_pilot_takeover_stop_and_land() -> None:
    params = {"COM_DISARM_LAND": 0.5, "MPC_LAND_SPEED": 1.5}  # a quicker landing, same logic
    async with mavsdk_on_sim(wind=WindConfig(mean_mps=3.0, gust_sigma_mps=0.5), seed=4, params=params) as c:
        await armable(c)
        await c.action.arm()
        await c.action.takeoff()  # MIS_TAKEOFF_ALT 2.5 m
        await climb_to(c, 2.2)
        await mode_is(c, FlightMode.HOLD, 5.0)  # AUTO.TAKEOFF ends in AUTO.LOITER

        await c.offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, 0.0))
        await c.offboard.start()
        north0_m = (await c.telemetry.position_velocity_ned()).position.north_m
        await c.offboard.set_velocity_ned(VelocityNedYaw(2.0, 0.0, 0.0, 0.0))
        await asyncio.sleep(2.0)
        pv = await c.telemetry.position_velocity_ned()
        assert pv.position.north_m - north0_m > 2.0
        assert await c.telemetry.flight_mode() == FlightMode.OFFBOARD

        # A pilot switches to POSCTL: MAVSDK's flight_mode stream shows it with the next 1 Hz heartbeat.
        seen = asyncio.create_task(first(c.telemetry.subscribe_flight_mode(), lambda m: m == FlightMode.POSCTL, 5.0))
        await asyncio.sleep(0.3)  # let the subscription register
        assert c.sim.pilot_address is not None
        result = await asyncio.to_thread(pilot.set_mode, "POSCTL", "127.0.0.1", c.sim.pilot_address[1], 5.0)
        assert result.ok, result.message
        switched_s = asyncio.get_running_loop().time()
        await seen
        seen_s = asyncio.get_running_loop().time() - switched_s
        print(f"MAVSDK's flight_mode showed POSCTL after {seen_s:.3f} s (1 Hz HEARTBEAT)")
        assert seen_s < 2.5  # one heartbeat period plus a generous margin for a loaded machine

        await c.offboard.stop()
        await mode_is(c, FlightMode.HOLD)
        await c.action.land()
        await first(c.telemetry.subscribe_armed(), lambda armed: not armed, 15.0)
        truth = c.sim.truth()
        assert truth is not None and truth.pos_ned_m[2] == 0.0


async def test_ardupilot_profile_streams_on_request_guided_reads_offboard_brake_reads_hold() -> None:
    async with mavsdk_on_sim(profile=Profile.ARDUPILOT, wind=WindConfig.off(), params={"LAND_SPEED": 120}) as c:
        assert await c.system.autopilot_type() == MavAutopilot.ARDUPILOT
        with pytest.raises(TimeoutError):  # ArduPilot streams nothing but HEARTBEAT unasked
            await first(c.telemetry.subscribe_position_velocity_ned(), lambda _: True, 1.5)
        await c.telemetry.set_rate_position_velocity_ned(20.0)
        await first(c.telemetry.subscribe_position_velocity_ned(), lambda _: True, 3.0)

        await c.action.set_takeoff_altitude(3.0)  # kept by MAVSDK, sent as NAV_TAKEOFF param7
        await eventually(lambda: c.sim.stack.prearm_ok, 5.0)
        await c.action.arm()
        await c.action.takeoff()  # MAVSDK: GUIDED, then NAV_TAKEOFF
        await mode_is(c, FlightMode.OFFBOARD)
        await climb_to(c, 2.8)

        await c.offboard.set_velocity_ned(VelocityNedYaw(2.0, 0.0, 0.0, 0.0))
        await c.offboard.start()
        await asyncio.sleep(2.0)
        assert (await c.telemetry.position_velocity_ned()).position.north_m > 2.0
        await c.offboard.stop()  # MAVSDK 4.1 sends BRAKE (17)
        await mode_is(c, FlightMode.HOLD)
        truth = c.sim.truth()
        assert truth is not None and truth.mode is Mode.AP_BRAKE
        await asyncio.sleep(2.0)
        truth = c.sim.truth()
        assert truth is not None and math.hypot(*truth.vel_ned_mps[:2]) < 0.3

        await c.action.land()
        await first(c.telemetry.subscribe_armed(), lambda armed: not armed, 15.0)


async def test_mavsdk_gripper_plugin_closes_and_opens_the_simulated_gripper() -> None:
    """MAV_CMD_DO_GRIPPER as the pickup's GRAB sends it (MAVSDK's gripper plugin, instance 1)."""
    from mavsdk.asyncio.plugins.gripper import GripperAsync

    async with mavsdk_on_sim(wind=WindConfig.off()) as c:
        gripper = GripperAsync(c.system)
        assert not c.sim.stack.gripper_closed
        await gripper.grab(1)
        assert c.sim.stack.gripper_closed  # the vehicle's side: closed
        await gripper.release(1)
        assert not c.sim.stack.gripper_closed
