"""The vehicle at the water, for the pickup's actions: how GRAB knows it is on it (``WaterContact``) and how a
climb leaves it (``off_the_water``: ArduCopter takes off from the water only with NAV_TAKEOFF)."""

from __future__ import annotations

import asyncio
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING

from app.errors import VehicleError
from app.messages import Autopilot, LandedState

if TYPE_CHECKING:
    from app.missions.actions import MissionIO
    from app.missions.pickup import PickupEstimates

CONTACT_POLL_S = 0.02  # GRAB looks for the water this often (the setpoint rate)
CONTACT_SETTLE_S = 0.1  # … and judges the sinking speed only this long after it began (it may enter slow)


CONTACT_STOP_WINDOW_S = 0.2  # a stop is judged against the fastest sinking of this long before
SINKING_MPS = 0.2  # held up by the water: not sinking after it had been sinking at least this fast …
CONTACT_HELD_S = 0.5  # … or this long after GRAB began (it came in on the water already)


class WaterContact:
    """Whether GRAB's vehicle, asked down since ``since_s``, is on the water (``on_it``, polled): the autopilot says
    landed; or it stopped — its down speed fell by ``grab_contact_drop_mps`` from the fastest of the last
    ``CONTACT_STOP_WINDOW_S``: the water met it; or it sinks no faster than ``grab_contact_speed_mps`` (the water
    holds it up) once it has been sinking (``SINKING_MPS``) or ``CONTACT_HELD_S`` after the start. (The
    autopilots' land detectors take 0.5 s and more to say so, and the object orbits decimetres meanwhile; a
    vehicle that met water falling away under it — a trough passing — went on sinking after it at 0.1-0.4 m/s,
    and with the speed check alone the gripper closed 0.28 s after the contact, 0.15 m off. A vehicle that came
    into GRAB climbing — back from an off-target touchdown and at once down again — passed through zero on its
    way to sinking, and with the speed check alone the gripper closed 0.33 m over the water.)"""

    def __init__(self, io: MissionIO, since_s: float) -> None:
        self.io, self.since_s = io, since_s
        self._recent: deque[tuple[float, float]] = deque()  # (t_s, down speed)
        self._sank = False  # it has been sinking since ``since_s``

    def on_it(self) -> bool:
        io = self.io
        if landed(io):
            return True
        pv, now_s = io.boundary.telemetry().pos_vel, io.now_s()
        if pv is None:
            return False
        down_mps, recent = pv.vel_ned_mps[2], self._recent
        recent.append((now_s, down_mps))
        while recent[0][0] < now_s - CONTACT_STOP_WINDOW_S:
            recent.popleft()
        self._sank = self._sank or down_mps >= SINKING_MPS
        in_grab_s = now_s - self.since_s
        if in_grab_s < CONTACT_SETTLE_S:
            return False
        if max(v for _, v in recent) - down_mps >= io.params.grab_contact_drop_mps:
            return True  # stopped
        return down_mps <= io.params.grab_contact_speed_mps and (self._sank or in_grab_s >= CONTACT_HELD_S)


WATER_WATCH_S = 5.0  # how long a climb from the water is watched for ArduCopter's land detector
NEAR_WATER_M = 1.0  # a climb starting this close to the sea is watched
TAKEOFF_ATTEMPTS = 3  # NAV_TAKEOFF from the water, tried this often (0.5 s apart) while still landed


def landed(io: MissionIO) -> bool:
    ls = io.boundary.telemetry().landed_state
    return ls is not None and ls.value is LandedState.ON_GROUND


def near_the_water(io: MissionIO, m: PickupEstimates) -> bool:
    """Within ``NEAR_WATER_M`` of the sea by the radar, or by the altitude over the tracked mean sea."""
    now_s = io.now_s()
    heights = (m.height_above_sea_m(now_s), m.height_over_mean_sea_m(now_s))
    return any(h is not None and h <= NEAR_WATER_M for h in heights)


async def off_the_water(io: MissionIO, m: PickupEstimates, engage: Callable[[], None], climb_m: float) -> None:
    """``engage`` the climb; on ArduPilot, watch it leave the water and take off when velocity will not do.

    PX4 takes off in OFFBOARD when the setpoint climbs. ArduCopter does not: once its land detector has set
    land_complete (it may do so a moment after the climb began, the vehicle still on the water), GUIDED's velocity
    control keeps the motors at ground idle (and DISARM_DELAY runs), and only a NAV_TAKEOFF leaves the ground.
    So on ArduPilot, while landed within ``WATER_WATCH_S``: leave offboard (zero velocity, then BRAKE — MAVSDK
    would otherwise keep re-sending our setpoint, which cancels a guided takeoff), take off in GUIDED to
    ``climb_m`` above where it sits (the altitude is above home), wait until it is off the water and that high,
    take offboard again and ``engage`` once more. The state's timeout bounds the waits; an abort or a takeover
    cancels them."""
    engage()
    if io.boundary.vehicle.autopilot is not Autopilot.ARDUPILOT or not (landed(io) or near_the_water(io, m)):
        return
    h0 = io.boundary.telemetry().height_above_home_m() or 0.0
    t_end_s = io.now_s() + WATER_WATCH_S
    while not landed(io):
        h = io.boundary.telemetry().height_above_home_m()
        if io.now_s() >= t_end_s or (h is not None and h >= h0 + climb_m / 2.0):
            return  # climbing on velocity setpoints: it was not landed
        await asyncio.sleep(0.05)
    target_m = max(h0 + climb_m, climb_m)
    io.setpoints.disengage()
    await io.boundary.leave_offboard("takeoff from the water (ArduPilot: NAV_TAKEOFF)")
    for attempt in range(TAKEOFF_ATTEMPTS):
        try:
            await io.boundary.takeoff(target_m)
            break
        except VehicleError:
            if not landed(io):  # a trough took the water away meanwhile: flying again, velocity will do
                await io.boundary.start_offboard()
                engage()
                return
            if attempt + 1 == TAKEOFF_ATTEMPTS:
                raise
            await asyncio.sleep(0.5)
    while True:
        h = io.boundary.telemetry().height_above_home_m()
        if not landed(io) and h is not None and h >= target_m - io.params.altitude_tolerance_m:
            break
        await asyncio.sleep(0.1)
    await io.boundary.start_offboard()
    engage()
