"""Entry actions: the only place a mission commands the vehicle. Named in the mission table.

Actions command through ``VehicleBoundary`` (``io.boundary``), which refuses anything that is not ours to
send (the pilot has control, an abort is under way) and sets the flight modes to expect. Each action says
which state ``control`` kinds may use it (checked when the table is loaded). The runner runs a state's
actions as one cancellable task: a takeover or an abort cancels them at their next await.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Protocol

from app.missions.circle import CircleMission
from app.missions.estimates import MissionModel
from app.missions.params import MissionParams
from app.offboard.boundary import VehicleBoundary
from app.offboard.setpoint_loop import SetpointLoop


class MissionIO(Protocol):
    boundary: VehicleBoundary
    setpoints: SetpointLoop
    params: MissionParams
    mission: MissionModel

    def now_s(self) -> float: ...


Action = Callable[[MissionIO], Awaitable[None]]


@dataclass(frozen=True, slots=True)
class ActionSpec:
    fn: Action
    control: tuple[str, ...] | None  # state control kinds allowed; None: any
    model: str | None = None  # the mission model it works on (``runner.MISSION_MODELS``), if any


async def arm(io: MissionIO) -> None:
    await io.boundary.arm()


async def takeoff(io: MissionIO) -> None:
    await io.boundary.takeoff(io.params.takeoff_altitude_m)


async def start_offboard(io: MissionIO) -> None:
    """Zero setpoint, OFFBOARD, then the setpoint loop holds position until a target is set."""
    await io.boundary.start_offboard()
    io.setpoints.engage(None)


async def start_circle(io: MissionIO) -> None:
    """Track the thesis's circle target, starting at the vehicle's current position."""
    pv = io.boundary.telemetry().pos_vel
    if pv is None:
        return  # the loop keeps holding; position_lost will abort
    if not isinstance(io.mission, CircleMission):
        raise TypeError(f"start_circle needs the circle mission, not {type(io.mission).__name__}")
    p = io.params
    circle = io.mission.start(pv.pos_ned_m, io.now_s(), p.circle_radius_m, p.circle_v_reduction_s, p.tracking_settle_s)
    io.setpoints.engage(circle)


async def hold_position(io: MissionIO) -> None:
    io.setpoints.engage(None)


async def land(io: MissionIO) -> None:
    await io.boundary.land()


async def stop_and_hold(io: MissionIO) -> None:
    """ABORT: zero velocity then HOLD if we own offboard, else HOLD if armed (shielded, bounded)."""
    io.setpoints.disengage()
    await io.boundary.abort_stop("abort")


ACTIONS: dict[str, ActionSpec] = {
    "arm": ActionSpec(arm, ("autopilot",)),
    "takeoff": ActionSpec(takeoff, ("autopilot",)),
    "start_offboard": ActionSpec(start_offboard, ("offboard",)),
    "start_circle": ActionSpec(start_circle, ("offboard",), "circle"),
    "hold_position": ActionSpec(hold_position, ("offboard",)),
    "land": ActionSpec(land, ("autopilot",)),
    "stop_and_hold": ActionSpec(stop_and_hold, None),
}
