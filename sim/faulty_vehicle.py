"""The in-process simulated autopilot with faults it can be told to show (``FaultyVehicle``), and a stalled event
loop (``stall_loop``): what ``sim.faults``' matrix and the preemption tests inject, all on the loop's clock."""

from __future__ import annotations

import asyncio
import collections
import math
from collections.abc import Awaitable, Callable
from dataclasses import replace
from typing import Any

import looptime

from app.errors import VehicleError
from app.messages import AttitudeEuler, PositionVelocityNed, TelemetrySnapshot, Vec3
from sim.autopilot_modes import MavResult, Mode, Profile
from sim.inproc import InProcessVehicle
from sim.stack_types import PositionTarget

NOOP_CYCLES = 2  # the looptime loop's setting (a stall re-creates it with the same)
COMMAND_TIMEOUT_S = 1.5  # MAVSDK: 0.5 s × 3 tries before a command times out
MAV_COMMAND = {
    "arm": "COMPONENT_ARM_DISARM",
    "takeoff": "NAV_TAKEOFF",
    "start_offboard": "DO_SET_MODE",
    "land": "NAV_LAND",
    "hold": "DO_SET_MODE",
    "stop_offboard": "DO_SET_MODE",
}

IGNORED_MODE = {
    ("start_offboard", Profile.PX4): Mode.OFFBOARD,
    ("start_offboard", Profile.ARDUPILOT): Mode.AP_GUIDED,
}


class FaultyVehicle(InProcessVehicle):
    """The in-process vehicle with faults switched on from outside (all on the loop's clock)."""

    def __init__(self, **kw: Any) -> None:
        super().__init__(**kw)
        self.slow_s: dict[str, float] = {}  # command → seconds before it reaches the vehicle (once)
        self.refuse: set[str] = set()  # commands answered COMMAND_DENIED
        self.ignore: set[str] = set()  # commands ACKed as accepted and never carried out
        self.after: dict[str, Callable[[], None]] = {}  # command → what happens right after it (once)
        self.delay_s = 0.0  # one-way MAVLink delay: telemetry, setpoints and commands
        self.link_lost = False
        self.heartbeat_lost = False
        self.position_frozen = False
        self.nan_until_s = -math.inf
        self.nan_streams = {"position", "attitude"}
        self._history: collections.deque[tuple[float, TelemetrySnapshot]] = collections.deque()
        self._frozen: TelemetrySnapshot | None = None
        self._acting = False

    # -- telemetry, as the app would receive it --------------------------------------------------

    def telemetry(self) -> TelemetrySnapshot:
        tel = super().telemetry()
        if tel.pos_vel is None:
            return tel
        now_s = tel.pos_vel.t_s
        self._history.append((now_s, tel))
        while len(self._history) > 2 and self._history[1][0] <= now_s - max(1.0, 2 * self.delay_s):
            self._history.popleft()
        if self.delay_s > 0.0:
            tel = next((s for t, s in reversed(self._history) if t <= now_s - self.delay_s), self._history[0][1])
        if self.link_lost:
            self._frozen = self._frozen or tel
            return self._frozen
        frozen = self._frozen
        if self.position_frozen:
            frozen = self._frozen = frozen or tel
            tel = replace(tel, pos_vel=frozen.pos_vel)
        if self.heartbeat_lost:
            frozen = self._frozen = frozen or tel
            tel = replace(tel, heartbeat_t_s=frozen.heartbeat_t_s)
        pv, att = tel.pos_vel, tel.attitude
        if now_s < self.nan_until_s and pv is not None and att is not None:
            nan3 = (math.nan, math.nan, math.nan)
            if "position" in self.nan_streams:
                tel = replace(tel, pos_vel=PositionVelocityNed(pv.t_s, nan3, nan3))
            if "attitude" in self.nan_streams:
                tel = replace(tel, attitude=AttitudeEuler(att.t_s, math.nan, math.nan, math.nan))
        return tel

    # -- setpoints -------------------------------------------------------------------------------

    async def set_velocity_ned(self, vel_ned_mps: Vec3, yaw_rad: float) -> None:
        if self.link_lost:
            return  # UDP into the void: MAVSDK does not notice
        if self.delay_s > 0.0 and not self._acting:
            asyncio.get_running_loop().call_later(self.delay_s, self._arrive, vel_ned_mps, yaw_rad, "app")
            return
        await super().set_velocity_ned(vel_ned_mps, yaw_rad)

    def zero_velocity_now(self, yaw_rad: float) -> None:
        if self.link_lost:
            return
        if self.delay_s > 0.0:
            asyncio.get_running_loop().call_later(self.delay_s, self._arrive, (0.0, 0.0, 0.0), yaw_rad, "watchdog")
            return
        super().zero_velocity_now(yaw_rad)

    def _arrive(self, vel_ned_mps: Vec3, yaw_rad: float, origin: str) -> None:
        if not self.link_lost and (origin == "app" or self._stream is not None):
            self._set_stream(self._advance(), PositionTarget.velocity(vel_ned_mps, yaw_rad), origin)

    def lose_link(self) -> None:
        self.link_lost = True
        self._stream = None  # MAVSDK's re-sends no longer arrive either

    # -- commands --------------------------------------------------------------------------------

    async def _faulty(self, name: str, act: Callable[[], Awaitable[None]]) -> None:
        slow_s = self.slow_s.pop(name, 0.0)
        if slow_s:
            await asyncio.sleep(slow_s)
        if self.link_lost:
            await asyncio.sleep(COMMAND_TIMEOUT_S)
            raise VehicleError(name, "TIMEOUT", "no answer")
        if self.delay_s:
            await asyncio.sleep(self.delay_s)
        t_s = self._advance()
        if name in self.refuse:
            self._command(t_s, MAV_COMMAND[name], MavResult.DENIED)
            raise VehicleError(name, "COMMAND_DENIED")
        if name in self.ignore:
            self._command(t_s, MAV_COMMAND[name], MavResult.ACCEPTED, IGNORED_MODE.get((name, self.stack.profile)))
            self._record("fault", t_s, fault="command_ignored", command=name)
        else:
            self._acting = True
            try:
                await act()
            finally:
                self._acting = False
        hook = self.after.pop(name, None)
        if hook is not None:
            hook()
        if self.delay_s:
            await asyncio.sleep(self.delay_s)  # the ACK's way back

    async def arm(self) -> None:
        await self._faulty("arm", super().arm)

    async def takeoff(self, altitude_m: float) -> None:
        await self._faulty("takeoff", lambda: InProcessVehicle.takeoff(self, altitude_m))

    async def start_offboard(self, yaw_rad: float) -> None:
        await self._faulty("start_offboard", lambda: InProcessVehicle.start_offboard(self, yaw_rad))

    async def hold(self) -> None:
        await self._faulty("hold", super().hold)

    async def stop_offboard(self) -> None:
        await self._faulty("stop_offboard", super().stop_offboard)

    async def land(self) -> None:
        await self._faulty("land", super().land)


def stall_loop(seconds: float) -> None:
    """Block the event loop for ``seconds`` of its (virtual) time: every timer is late by that much."""
    loop = asyncio.get_running_loop()
    if not isinstance(loop, looptime.LoopTimeEventLoop):
        raise RuntimeError("a stall needs a looptime event loop")
    loop.setup_looptime(start=loop.time() + seconds, noop_cycles=NOOP_CYCLES)
