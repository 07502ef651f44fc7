"""The one gateway between the mission and the vehicle: authority, offboard ownership, envelope, watchdog.

Every command and every setpoint the app sends goes through ``VehicleBoundary``; nothing else calls the
``Vehicle``'s commands. It enforces, at the last moment before anything leaves:

- **Authority.** ``MISSION``: the mission commands. ``ABORTING``: only ABORT's own stop goes out (zero
  velocity, then HOLD). ``PILOT``: someone else switched the flight mode — nothing is commanded until the
  pilot hands back, except PX4's zero-velocity standby stream (which PX4 ignores outside OFFBOARD). Before
  every command and setpoint the freshest telemetry is checked for a takeover (``ModeWatch``), so a command
  that an action was about to send after the pilot's switch is refused, not sent.
- **One owner of offboard.** ``start_offboard`` marks us the owner; every way of leaving it on our own
  account (``leave_offboard``: state change, ABORT, FAILED, exception, cancellation, a second signal) sends
  zero velocity for ``exit_zero_s``, then HOLD — as one task, shielded from cancellation and bounded by
  ``exit_timeout_s``. A takeover ends ownership without sending anything, and so does a disarmed vehicle
  (only MAVSDK's re-sent setpoint is zeroed).
- **The envelope and finiteness** on every setpoint: velocity through ``apply_envelope`` at the latest
  position, yaw finite (else the last yaw sent); no position → zero velocity.
- **The setpoint watchdog** (``app.offboard.watchdog``), fed with every setpoint, engaged while we own
  offboard: if the event loop stalls, the adapter zeroes the re-sent setpoint from outside the loop.
- **Telemetry hygiene**: a sample with a NaN or inf is dropped and counted (the last good one stays, and
  ages into the stale/lost guards).
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable, Coroutine
from dataclasses import dataclass, replace
from enum import StrEnum
from typing import Any

from app.clock import Clock
from app.errors import CommandRefused, VehicleError
from app.eventlog import EventLog
from app.messages import Autopilot, FlightMode, LandedState, TelemetrySnapshot, Vec3
from app.offboard.envelope import Clamped, EnvelopeLimits, apply_envelope
from app.offboard.mode_watch import ModeWatch, Takeover
from app.offboard.vehicle import Vehicle
from app.offboard.watchdog import SetpointWatchdog

ZERO: Vec3 = (0.0, 0.0, 0.0)


class Authority(StrEnum):
    MISSION = "mission"
    ABORTING = "aborting"
    PILOT = "pilot"


@dataclass(frozen=True, slots=True)
class BoundaryParams:
    limits: EnvelopeLimits
    setpoint_period_s: float  # the rate zero setpoints go out at while leaving offboard
    exit_zero_s: float  # how long zero velocity is sent before HOLD
    exit_timeout_s: float  # the whole exit (zeros + HOLD) is bounded by this
    watchdog_timeout_s: float
    position_stale_s: float


@dataclass(frozen=True, slots=True)
class LinkHealth:
    """What the guards need to know about the link, at ``t_s``."""

    t_s: float
    heartbeat_age_s: float | None  # None: never heard
    position_age_s: float | None
    attitude_age_s: float | None
    send_failures: int  # consecutive failed setpoint sends
    non_finite_samples: int  # telemetry samples dropped for NaN/inf


def _finite(*xs: float) -> bool:
    return all(map(math.isfinite, xs))


async def shielded(task: asyncio.Task[None], timeout_s: float) -> None:
    """Await ``task``; if we are cancelled meanwhile, let it finish (up to ``timeout_s``), then re-raise."""
    try:
        await asyncio.shield(task)
    except asyncio.CancelledError:
        if not task.done():
            await asyncio.wait({task}, timeout=timeout_s)
        raise


class VehicleBoundary:
    def __init__(self, vehicle: Vehicle, clock: Clock, events: EventLog, params: BoundaryParams) -> None:
        self.vehicle = vehicle
        self._clock = clock
        self._events = events
        self.params = params
        self.authority = Authority.MISSION
        self.owns_offboard = False
        self.flying = False  # the mission is in a state that flies the vehicle (set by the runner)
        self.watch = ModeWatch()
        self.on_takeover: Callable[[Takeover], None] | None = None
        self.send_failures = 0
        self.send_failures_total = 0
        self.non_finite_samples = 0
        self.refused: dict[str, int] = {}
        self.yaw_rad = 0.0  # the last yaw sent
        self._good = TelemetrySnapshot()
        self._clean: TelemetrySnapshot | None = None  # the vehicle's last snapshot, when it needed no mending
        self._leaving: asyncio.Task[None] | None = None
        self._last_offboard_command_s: float | None = None
        self.watchdog = SetpointWatchdog(params.watchdog_timeout_s, self._watchdog_fired)
        vehicle.attach_watchdog(self.watchdog)

    # ---- telemetry ------------------------------------------------------------------------------

    def telemetry(self) -> TelemetrySnapshot:
        """The vehicle's snapshot with non-finite samples replaced by the last good ones (and counted)."""
        tel = self.vehicle.telemetry()
        if tel is self._clean:
            return self._good  # the very snapshot checked last time (an adapter may hand the same one out again)
        good = self._good
        pv, att, home = tel.pos_vel, tel.attitude, tel.home_ned_m
        if pv is not None and pv is not good.pos_vel and not _finite(*pv.pos_ned_m, *pv.vel_ned_mps, pv.t_s):
            self._reject("position", pv.t_s)
            pv = good.pos_vel
        if att is not None and att is not good.attitude and not _finite(att.roll_rad, att.pitch_rad, att.yaw_rad):
            self._reject("attitude", att.t_s)
            att = good.attitude
        if home is not None and not _finite(*home):
            home = good.home_ned_m
        clean = pv is tel.pos_vel and att is tel.attitude and home is tel.home_ned_m
        self._clean = tel if clean else None
        self._good = tel if clean else replace(tel, pos_vel=pv, attitude=att, home_ned_m=home)
        return self._good

    def _reject(self, stream: str, t_s: float) -> None:
        self.non_finite_samples += 1
        self._events.write(self._clock.now_s(), "vehicle", event="non_finite_sample", stream=stream, sample_t_s=t_s)

    def health(self, now_s: float) -> LinkHealth:
        tel = self.telemetry()

        def age(t: float | None) -> float | None:
            return None if t is None else now_s - t

        return LinkHealth(
            now_s,
            age(tel.heartbeat_t_s),
            age(tel.pos_vel.t_s if tel.pos_vel else None),
            age(tel.attitude.t_s if tel.attitude else None),
            self.send_failures,
            self.non_finite_samples,
        )

    # ---- who has the vehicle --------------------------------------------------------------------

    def check_takeover(self) -> Takeover | None:
        """Judge the latest flight-mode sample; a takeover while flying hands the vehicle to the pilot."""
        tel = self.telemetry()
        if tel.flight_mode is None:
            return None
        on_ground = tel.landed_state is not None and tel.landed_state.value is LandedState.ON_GROUND
        takeover = self.watch.observe(tel.mode(), tel.flight_mode.t_s, on_ground=on_ground)
        if takeover is None or not self.commanding or self.authority is Authority.PILOT:
            return None
        self._hand_to_pilot(takeover)
        return takeover

    @property
    def commanding(self) -> bool:
        """The mission flies the vehicle: a flying state, an abort under way, or offboard being left."""
        return self.flying or self.authority is Authority.ABORTING or self._leaving is not None

    def _hand_to_pilot(self, takeover: Takeover) -> None:
        now_s = self._clock.now_s()
        self.authority = Authority.PILOT
        if self.owns_offboard:
            # MAVSDK keeps re-sending our last setpoint; from now on it re-sends zero velocity (the standby).
            self.vehicle.zero_velocity_now(self.yaw_rad)
        self.owns_offboard = False
        self.watchdog.disengage()
        self.watch.clear(now_s)
        self._events.write(now_s, "run", event="takeover", by=takeover.by, mode=takeover.mode.value)
        if self.on_takeover is not None:
            self.on_takeover(takeover)

    def may_hand_back(self, late_command_s: float) -> bool:
        """The pilot selected OFFBOARD (ArduPilot: GUIDED) — not our own mode command landing late."""
        tel = self.telemetry()
        if self.authority is not Authority.PILOT or tel.mode() is not FlightMode.OFFBOARD or not tel.is_armed():
            return False
        last = self._last_offboard_command_s
        return last is None or self._clock.now_s() - last > late_command_s

    def hand_back(self) -> None:
        self.authority = Authority.MISSION
        self._events.write(self._clock.now_s(), "run", event="handback")

    def request_abort(self) -> None:
        """From now on only ABORT's own stop goes out (nothing at all while the pilot has control)."""
        if self.authority is Authority.MISSION:
            self.authority = Authority.ABORTING

    # ---- commands -------------------------------------------------------------------------------

    def _require(self, name: str, *, aborting_ok: bool = False) -> None:
        self.check_takeover()
        a = self.authority
        if a is Authority.MISSION or (a is Authority.ABORTING and aborting_ok):
            return
        self.refused[name] = self.refused.get(name, 0) + 1
        self._events.write(self._clock.now_s(), "command", name=name, result="refused", authority=a.value)
        raise CommandRefused(name, a.value)

    async def _command(
        self,
        name: str,
        call: Callable[[], Coroutine[Any, Any, None]],
        expect: frozenset[FlightMode] | None = None,
        *,
        aborting_ok: bool = False,
    ) -> None:
        self._require(name, aborting_ok=aborting_ok)
        if expect is not None:
            self.watch.expect(expect, self._clock.now_s())
        try:
            await call()
        except VehicleError as e:
            self._events.write(self._clock.now_s(), "command", name=name, result=e.result, error=str(e))
            raise
        self._events.write(self._clock.now_s(), "command", name=name, result="ok")

    async def arm(self) -> None:
        await self._command("arm", self.vehicle.arm)

    async def takeoff(self, altitude_m: float) -> None:
        # PX4: AUTO.TAKEOFF then AUTO.LOITER; ArduPilot: GUIDED (reads as OFFBOARD).
        ap = self.vehicle.autopilot is Autopilot.ARDUPILOT
        modes = {FlightMode.OFFBOARD} if ap else {FlightMode.TAKEOFF, FlightMode.HOLD}
        await self._command("takeoff", lambda: self.vehicle.takeoff(altitude_m), frozenset(modes))

    async def start_offboard(self) -> None:
        """Zero setpoint, then OFFBOARD (ArduPilot GUIDED); from here on we own offboard until we leave it."""
        self._require("start_offboard")
        att = self.telemetry().attitude
        self.yaw_rad = att.yaw_rad if att is not None else self.yaw_rad
        self.owns_offboard = True  # before the call: a cancelled or failed start is still left properly
        self.watchdog.engage(self._clock.now_s())
        self._last_offboard_command_s = self._clock.now_s()
        await self._command("start_offboard", lambda: self.vehicle.start_offboard(self.yaw_rad), _OFFBOARD)
        self.watchdog.feed(self._clock.now_s())

    async def land(self) -> None:
        await self._command("land", self.vehicle.land, frozenset({FlightMode.LAND}))

    async def grip(self, closed: bool) -> None:
        await self._command("gripper_grab" if closed else "gripper_release", lambda: self.vehicle.grip(closed))

    async def hold(self, *, aborting_ok: bool = False) -> None:
        await self._command("hold", self.vehicle.hold, _HOLD, aborting_ok=aborting_ok)

    # ---- setpoints ------------------------------------------------------------------------------

    @property
    def accepts_guidance(self) -> bool:
        return self.authority is Authority.MISSION and self.owns_offboard and self._leaving is None

    async def send_velocity(
        self, vel_ned_mps: Vec3, yaw_rad: float, *, allow_below_min: bool = False
    ) -> Clamped | None:
        """One guidance setpoint through the envelope; ``None`` when refused (not ours to send now)."""
        self.check_takeover()
        if not self.accepts_guidance:
            self.refused["setpoint"] = self.refused.get("setpoint", 0) + 1
            return None
        tel = self.telemetry()
        pv = tel.pos_vel
        now_s = self._clock.now_s()
        if pv is None or now_s - pv.t_s > self.params.position_stale_s:
            clamped = Clamped(ZERO, ("no_position",))
        else:
            home = tel.home_ned_m or (0.0, 0.0, 0.0)
            clamped = apply_envelope(
                vel_ned_mps, pv.pos_ned_m, home, self.params.limits, allow_below_min=allow_below_min
            )
        if not math.isfinite(yaw_rad):
            yaw_rad = self.yaw_rad
            clamped = Clamped(clamped.vel_ned_mps, (*clamped.limits, "non_finite_yaw"))
        await self._send(clamped.vel_ned_mps, yaw_rad)
        return clamped

    async def send_standby(self) -> None:
        """PX4 only, while the pilot has control: zero velocity so the pilot can hand back by selecting OFFBOARD."""
        if self.authority is Authority.PILOT:
            await self._send(ZERO, self.yaw_rad)

    async def _send(self, vel: Vec3, yaw_rad: float) -> None:
        try:
            await self.vehicle.set_velocity_ned(vel, yaw_rad)
        except VehicleError as e:
            self.send_failures += 1
            self.send_failures_total += 1
            self._events.write(self._clock.now_s(), "setpoint", decision="send_failed", error=str(e))
            return
        self.send_failures = 0
        self.yaw_rad = yaw_rad
        self.watchdog.feed(self._clock.now_s())

    def _watchdog_fired(self, now_s: float, silent_s: float) -> None:
        """From the watchdog's thread: the loop sent nothing for ``silent_s``; zero the re-sent setpoint."""
        self.vehicle.zero_velocity_now(self.yaw_rad)
        self._events.write(now_s, "setpoint", decision="watchdog_zero", silent_s=silent_s, vel=list(ZERO))

    # ---- leaving offboard -----------------------------------------------------------------------

    async def leave_offboard(self, reason: str) -> None:
        """Zero velocity for ``exit_zero_s``, then HOLD — if we own offboard. Shielded and bounded."""
        if not self.owns_offboard or self.authority is Authority.PILOT:
            return
        armed = self.telemetry().armed
        if self._leaving is None and armed is not None and not armed.value:
            self._disowned_disarmed(reason)
            return
        if self._leaving is None:
            self._leaving = asyncio.get_running_loop().create_task(self._leave(reason), name="offboard.leave")
        await shielded(self._leaving, self.params.exit_timeout_s)

    async def leave_settled(self) -> None:
        """Wait (bounded) for a leave_offboard already under way to send its HOLD: until then ``owns_offboard`` still
        says True of an offboard that is about to end."""
        leaving = self._leaving
        if leaving is not None and not leaving.done():
            await asyncio.wait({leaving}, timeout=self.params.exit_timeout_s)

    def _disowned_disarmed(self, reason: str) -> None:
        """The vehicle is disarmed (a kill switch, an auto-disarm): nothing to stop and no mode to change — a mode
        command now would only override whoever disarmed it. MAVSDK's re-sent setpoint becomes zero velocity,
        so nothing stale flies if it is armed again in OFFBOARD."""
        self.vehicle.zero_velocity_now(self.yaw_rad)
        self.owns_offboard = False
        self.watchdog.disengage()
        self._events.write(self._clock.now_s(), "run", event="leave_offboard", reason=reason, action="none_disarmed")

    async def _leave(self, reason: str) -> None:
        p = self.params
        events, clock = self._events, self._clock
        events.write(clock.now_s(), "run", event="leave_offboard", reason=reason, action="zero_velocity_then_hold")
        try:
            async with asyncio.timeout(p.exit_timeout_s):
                for _ in range(max(1, round(p.exit_zero_s / p.setpoint_period_s))):
                    if self._pilot_now():
                        return
                    await self._send(ZERO, self.yaw_rad)
                    events.write(clock.now_s(), "setpoint", decision="exit_zero", vel=list(ZERO))
                    await clock.sleep(p.setpoint_period_s)
                if self._pilot_now():
                    return
                self.watch.expect(_HOLD, clock.now_s())
                await self.vehicle.stop_offboard()
            events.write(clock.now_s(), "command", name="stop_offboard", result="ok")
        except (VehicleError, TimeoutError) as e:
            events.write(clock.now_s(), "command", name="stop_offboard", result="failed", error=str(e) or "timeout")
        finally:
            self.owns_offboard = False
            self.watchdog.disengage()
            self._leaving = None

    def _pilot_now(self) -> bool:
        self.check_takeover()
        return self.authority is Authority.PILOT

    async def abort_stop(self, reason: str) -> None:
        """ABORT: zero velocity then HOLD if we own offboard, else HOLD if armed; nothing if the pilot has control."""
        self.request_abort()
        if self.authority is Authority.PILOT:
            self._events.write(self._clock.now_s(), "command", name="abort_stop", result="skipped_pilot_control")
            return
        if self.owns_offboard:
            await self.leave_offboard(reason)
        elif self.telemetry().is_armed():
            task = asyncio.get_running_loop().create_task(self.hold(aborting_ok=True), name="offboard.abort_hold")
            await shielded(task, self.params.exit_timeout_s)

    async def release(self, reason: str) -> None:
        """The safe exit on the way out: leave offboard if we still own it; stop the watchdog."""
        try:
            await self.leave_offboard(reason)
        finally:
            self.watchdog.disengage()


_OFFBOARD = frozenset({FlightMode.OFFBOARD})
_HOLD = frozenset({FlightMode.HOLD})
