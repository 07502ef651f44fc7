"""Entry actions: the only place a mission commands the vehicle. Named in the mission table.

Each action says whether it commands the vehicle (the runner never runs those while the pilot has
control) and which state ``control`` kinds may use it (checked when the table is loaded). An action that
changes the flight mode tells the runner which modes to expect, so any other mode seen afterwards is
recognised as someone else taking over.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Protocol

from app.messages import FlightMode
from app.missions.circle import CircleTarget, TrackingErrors
from app.missions.params import MissionParams
from app.offboard.setpoint_loop import LoopMode, SetpointLoop
from app.offboard.vehicle import Vehicle


class MissionIO(Protocol):
    vehicle: Vehicle
    setpoints: SetpointLoop
    params: MissionParams
    tracking: TrackingErrors

    def now_s(self) -> float: ...

    def expect_modes(self, modes: frozenset[FlightMode]) -> None: ...


Action = Callable[[MissionIO], Awaitable[None]]


@dataclass(frozen=True, slots=True)
class ActionSpec:
    fn: Action
    commands_vehicle: bool
    control: tuple[str, ...] | None  # state control kinds allowed; None: any


async def arm(io: MissionIO) -> None:
    await io.vehicle.arm()


async def takeoff(io: MissionIO) -> None:
    # PX4: AUTO.TAKEOFF then AUTO.LOITER; ArduPilot: GUIDED (reads as OFFBOARD).
    io.expect_modes(frozenset({FlightMode.TAKEOFF, FlightMode.HOLD, FlightMode.OFFBOARD}))
    await io.vehicle.takeoff(io.params.takeoff_altitude_m)


async def start_offboard(io: MissionIO) -> None:
    """Zero setpoint, OFFBOARD, then the setpoint loop holds position until a target is set."""
    tel = io.vehicle.telemetry()
    yaw_rad = tel.attitude.yaw_rad if tel.attitude else 0.0
    io.expect_modes(frozenset({FlightMode.OFFBOARD}))
    await io.vehicle.start_offboard(yaw_rad)
    io.setpoints.engage(None)


async def start_circle(io: MissionIO) -> None:
    """Track the thesis's circle target, starting at the vehicle's current position."""
    pv = io.vehicle.telemetry().pos_vel
    if pv is None:
        return  # the loop keeps holding; position_lost will abort
    p = io.params
    circle = CircleTarget(
        pv.pos_ned_m, io.now_s(), p.circle_radius_m, p.circle_v_reduction_s, p.tracking_settle_s, io.tracking
    )
    io.setpoints.engage(circle)


async def hold_position(io: MissionIO) -> None:
    io.setpoints.engage(None)


async def land(io: MissionIO) -> None:
    io.setpoints.disengage()
    io.expect_modes(frozenset({FlightMode.LAND}))
    await io.vehicle.land()


async def stop_and_hold(io: MissionIO) -> None:
    """ABORT: if we are streaming setpoints, zero velocity then HOLD; else HOLD if still flying."""
    was_guiding = io.setpoints.mode == LoopMode.GUIDE
    io.setpoints.disengage()
    tel = io.vehicle.telemetry()
    if not tel.is_armed():
        return
    io.expect_modes(frozenset({FlightMode.HOLD}))
    if was_guiding:
        await io.vehicle.stop_offboard()
    else:
        await io.vehicle.hold()


ACTIONS: dict[str, ActionSpec] = {
    "arm": ActionSpec(arm, True, ("autopilot",)),
    "takeoff": ActionSpec(takeoff, True, ("autopilot",)),
    "start_offboard": ActionSpec(start_offboard, True, ("offboard",)),
    "start_circle": ActionSpec(start_circle, True, ("offboard",)),
    "hold_position": ActionSpec(hold_position, True, ("offboard",)),
    "land": ActionSpec(land, True, ("autopilot",)),
    "stop_and_hold": ActionSpec(stop_and_hold, True, None),
}
