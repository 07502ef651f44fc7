"""In-process vehicle: the app's Vehicle protocol on the simulated stack, in virtual (loop) time."""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import math
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager

import pytest

from app.errors import VehicleConnectionError, VehicleError
from app.messages import Autopilot, FlightMode, LandedState
from app.offboard.vehicle import Vehicle
from sim.autopilot_modes import Profile
from sim.inproc import InProcessVehicle
from sim.wind import WindConfig

pytestmark = pytest.mark.looptime


@pytest.fixture
def vehicle() -> InProcessVehicle:
    # Built here but started inside each test: looptime virtualises the test's loop time only.
    return InProcessVehicle(seed=2, wind=WindConfig(mean_mps=4.0, gust_sigma_mps=0.5))


@asynccontextmanager
async def running(v: InProcessVehicle) -> AsyncIterator[InProcessVehicle]:
    task = asyncio.create_task(v.run())
    try:
        await v.wait_ready(timeout_s=5.0)
        yield v
    finally:
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task


async def until(predicate: Callable[[], bool], timeout_s: float, period_s: float = 0.05) -> None:
    """Poll ``predicate`` on the loop clock; fail after ``timeout_s``."""
    for _ in range(round(timeout_s / period_s)):
        if predicate():
            return
        await asyncio.sleep(period_s)
    raise AssertionError(f"not reached within {timeout_s} s")


async def wait_mode(v: InProcessVehicle, mode: FlightMode, timeout_s: float) -> None:
    await until(lambda: v.telemetry().mode() is mode, timeout_s)


async def fly_up(v: InProcessVehicle, altitude_m: float = 5.0) -> None:
    await v.arm()
    await v.takeoff(altitude_m)
    await wait_mode(v, FlightMode.HOLD, 15.0)


def test_it_implements_the_vehicle_protocol() -> None:
    vehicle: Vehicle = InProcessVehicle()  # a type error here means the protocol drifted
    assert vehicle.autopilot is Autopilot.PX4
    assert InProcessVehicle(profile=Profile.ARDUPILOT).autopilot is Autopilot.ARDUPILOT


async def test_wait_ready_needs_home_and_times_out_with_a_reason() -> None:
    v = InProcessVehicle(gps_fix_delay_s=30.0)
    with pytest.raises(VehicleConnectionError, match="home"):
        await v.wait_ready(timeout_s=2.0)


async def test_telemetry_is_stamped_with_loop_time(vehicle: InProcessVehicle) -> None:
    async with running(vehicle):
        await asyncio.sleep(1.0)
        snap = vehicle.telemetry()
        now_s = asyncio.get_running_loop().time()
        assert snap.pos_vel is not None and snap.attitude is not None and snap.flight_mode is not None
        assert now_s - 0.02 <= snap.pos_vel.t_s <= now_s
        assert snap.mode() is FlightMode.HOLD and not snap.is_armed()
        assert snap.landed_state is not None and snap.landed_state.value is LandedState.ON_GROUND
        # home is where the estimate put the vehicle at the GPS fix: the origin plus a second of GNSS wander
        assert snap.home_ned_m is not None and snap.home_ned_m != (0.0, 0.0, 0.0)
        assert snap.home_ned_m == pytest.approx((0.0, 0.0, 0.0), abs=0.05)


async def test_takeoff_offboard_velocity_stop_and_land(vehicle: InProcessVehicle) -> None:
    async with running(vehicle):
        await fly_up(vehicle, 5.0)
        assert vehicle.telemetry().height_above_home_m() == pytest.approx(5.0, abs=0.3)
        await vehicle.start_offboard(yaw_rad=0.0)
        assert vehicle.telemetry().mode() is FlightMode.OFFBOARD
        north0_m = vehicle.truth().pos_ned_m[0]
        for _ in range(150):  # 3 s at 50 Hz
            await vehicle.set_velocity_ned((2.0, 0.0, 0.0), 0.0)
            await asyncio.sleep(0.02)
        assert vehicle.truth().pos_ned_m[0] - north0_m > 4.0
        await vehicle.stop_offboard()
        assert vehicle.telemetry().mode() is FlightMode.HOLD
        await asyncio.sleep(3.0)
        assert math.hypot(*vehicle.truth().vel_ned_mps[:2]) < 0.3
        await vehicle.land()
        await until(lambda: not vehicle.telemetry().is_armed(), 20.0)
        assert vehicle.truth().landed_state is LandedState.ON_GROUND


async def test_refused_commands_raise_vehicle_error(vehicle: InProcessVehicle) -> None:
    async with running(vehicle):
        with pytest.raises(VehicleError) as err:
            await vehicle.takeoff(5.0)  # disarmed
        assert err.value.command == "takeoff" and err.value.result == "COMMAND_DENIED"
        await fly_up(vehicle)
        vehicle.pilot_set_mode(FlightMode.POSCTL)
        assert vehicle.telemetry().mode() is FlightMode.POSCTL


async def test_mavsdk_resend_keeps_offboard_alive_until_the_stream_stops(vehicle: InProcessVehicle) -> None:
    async with running(vehicle):
        await fly_up(vehicle)
        await vehicle.start_offboard(yaw_rad=0.0)
        await vehicle.set_velocity_ned((1.0, 0.0, 0.0), 0.0)
        await asyncio.sleep(5.0)  # the app sends nothing; "MAVSDK" re-sends the last setpoint
        assert vehicle.telemetry().mode() is FlightMode.OFFBOARD
        vehicle.stop_setpoint_stream()  # the companion computer stalls
        await asyncio.sleep(1.2)
        assert vehicle.telemetry().mode() is FlightMode.HOLD
        assert any(e.kind == "mode" and e.reason == "offboard_loss" for e in vehicle.events)


async def test_pilot_switch_away_from_offboard_ends_the_resend_after_the_watchdog(
    vehicle: InProcessVehicle,
) -> None:
    async with running(vehicle):
        await fly_up(vehicle)
        await vehicle.start_offboard(yaw_rad=0.0)
        await asyncio.sleep(4.0)
        vehicle.pilot_set_mode(FlightMode.POSCTL)
        await asyncio.sleep(0.5)
        assert vehicle._stream is None  # MAVSDK's watchdog: not OFFBOARD and >3 s since the stream started
        with pytest.raises(VehicleError):
            vehicle.pilot_set_mode(FlightMode.OFFBOARD)  # no stream, so OFFBOARD is not available


async def test_ardupilot_takeoff_goes_through_guided() -> None:
    v = InProcessVehicle(profile=Profile.ARDUPILOT, wind=WindConfig.off())
    task = asyncio.create_task(v.run())
    try:
        await v.wait_ready(5.0)
        await v.arm()
        await v.takeoff(4.0)
        assert v.telemetry().mode() is FlightMode.OFFBOARD  # GUIDED
        await asyncio.sleep(6.0)
        assert v.telemetry().height_above_home_m() == pytest.approx(4.0, abs=0.2)
        await v.hold()
        assert v.telemetry().mode() is FlightMode.HOLD  # BRAKE
    finally:
        task.cancel()


async def test_sample_listeners_feed_a_state_history_at_the_telemetry_rate() -> None:
    """The in-process vehicle hands every 50 Hz position and attitude sample to listeners, like MAVSDK does,
    so the state history the estimators interpolate in is fed the same way in virtual time."""
    from app.estimators.state_history import StateHistory
    from app.messages import AttitudeEuler, PositionVelocityNed

    v = InProcessVehicle(seed=1, wind=WindConfig.off())
    history, stamps = StateHistory(), []

    def listen(sample, received_s):
        stamps.append((type(sample).__name__, sample.t_s, received_s))
        if isinstance(sample, PositionVelocityNed):
            history.add_pos_vel(sample)
        elif isinstance(sample, AttitudeEuler):
            history.add_attitude(sample)

    v.add_sample_listener(listen)
    async with running(v):
        await fly_up(v, 5.0)
        hover_s = asyncio.get_running_loop().time()
        await asyncio.sleep(2.0)
        now_s = asyncio.get_running_loop().time()
        tel = v.telemetry()
    pos_times = [t for kind, t, _ in stamps if kind == "PositionVelocityNed"]
    gaps = [b - a for a, b in itertools.pairwise(pos_times)]
    assert len(pos_times) > 100 and min(gaps) >= 0.02 - 1e-6  # never faster than the 50 Hz stream
    # with nothing else asking, a sample every wake: none skipped for a wake a rounding error early
    hover_gaps = [b - a for a, b in itertools.pairwise(t for t in pos_times if t >= hover_s)]
    assert len(hover_gaps) >= 99 and max(hover_gaps) <= 0.02 + 1e-6
    assert all(t == r for _, t, r in stamps)  # stamped when taken: no link in between
    state = history.at(now_s - 0.5)
    assert state.pos_ned_m[2] == pytest.approx(tel.pos_vel.pos_ned_m[2], abs=0.05)  # hovering at 5 m


def test_samples_come_at_every_wake_on_the_evaluations_loop() -> None:
    """On the evaluation's virtual-time loop (integer microseconds read back as float seconds) a wake can come a
    rounding error before ``last + 20 ms``: the sample must still be handed out then, not a wake later."""
    from app.messages import PositionVelocityNed
    from sim.virtual_loop import VirtualTimeLoop

    async def hover_samples() -> list[float]:
        v = InProcessVehicle(seed=1)
        times: list[float] = []
        v.add_sample_listener(lambda s, t: times.append(t) if isinstance(s, PositionVelocityNed) else None)
        async with running(v):
            await asyncio.sleep(20.0)
        return times

    loop = VirtualTimeLoop()
    try:
        times = loop.run_until_complete(hover_samples())
    finally:
        loop.close()
    gaps = [b - a for a, b in itertools.pairwise(times)]
    assert len(gaps) >= 999
    assert min(gaps) >= 0.02 - 1e-6 and max(gaps) <= 0.02 + 1e-6
