"""The offboard setpoint loop: fixed rate, never silent while the mission has control.

Modes:
- ``GUIDE``: every period, constant-bearing guidance toward the target source; with no source, or when
  the source has no fresh estimate, it holds the position where the target was lost (a position hold,
  not zero velocity, which would drift in wind). Stale position telemetry → zero velocity until it is
  fresh again (the mission's ``position_lost`` guard acts after a while).
- ``STANDBY``: the pilot has control (PX4): zero-velocity setpoints at a low rate, only so the pilot can
  hand back by selecting OFFBOARD (PX4 refuses OFFBOARD without a setpoint stream; it ignores the stream
  in every other mode). No mode is ever commanded from here.
- ``OFF``: sends nothing.
Everything goes out through ``VehicleBoundary`` (authority, envelope, finiteness, watchdog); every
decision is written to the event log.
"""

from __future__ import annotations

from collections import deque
from enum import StrEnum
from typing import Protocol

from app.clock import Clock, sleep_until
from app.eventlog import EventLog
from app.messages import PositionVelocityNed, TargetState, Vec3, norm, sub
from app.offboard.boundary import VehicleBoundary
from app.offboard.guidance import ConstantBearingParams, constant_bearing_velocity
from app.stats import percentile


class LoopMode(StrEnum):
    OFF = "OFF"
    GUIDE = "GUIDE"
    STANDBY = "STANDBY"


class TargetSource(Protocol):
    """Where guidance should take the vehicle, as a function of loop time."""

    name: str

    def target_at(self, t_s: float) -> TargetState | None:
        """Target state at ``t_s``, or ``None`` when there is no fresh estimate (the loop then holds)."""
        ...

    def observe(self, sample: PositionVelocityNed) -> None:
        """Called once per new vehicle position sample (for tracking statistics)."""
        ...


class FixedPoint:
    """A target that does not move (hold a position)."""

    def __init__(self, name: str, pos_ned_m: Vec3) -> None:
        self.name = name
        self.pos_ned_m = pos_ned_m

    def target_at(self, t_s: float) -> TargetState:
        return TargetState(t_s, self.pos_ned_m, (0.0, 0.0, 0.0))

    def observe(self, sample: PositionVelocityNed) -> None:
        pass


class SetpointLoop:
    def __init__(
        self,
        boundary: VehicleBoundary,
        clock: Clock,
        events: EventLog,
        guidance: ConstantBearingParams,
        rate_hz: float,
        standby_rate_hz: float,
        position_stale_s: float,
    ) -> None:
        self._boundary = boundary
        self._clock = clock
        self._events = events
        self._guidance = guidance
        self._period_s = 1.0 / rate_hz
        self._standby_period_s = 1.0 / standby_rate_hz if standby_rate_hz > 0 else 0.0
        self._stale_s = position_stale_s
        self.mode = LoopMode.OFF
        self._source: TargetSource | None = None
        self._hold: FixedPoint | None = None  # where we hold while the source has no estimate
        self._yaw_rad = 0.0
        self._allow_below_min = False
        self._last_sample_t_s: float | None = None
        self._last_err_m: float | None = None
        self._next_standby_s = 0.0
        self.sent = 0
        self._last_send_s: float | None = None
        self.send_intervals_s: deque[float] = deque(maxlen=100_000)  # between guidance setpoints

    @property
    def period_s(self) -> float:
        return self._period_s

    # ---- control (called by the mission runner) -------------------------------------------------

    def engage(self, source: TargetSource | None, *, allow_below_min: bool = False) -> None:
        """Start guiding toward ``source``; ``None`` holds the current position."""
        tel = self._boundary.telemetry()
        if self.mode != LoopMode.GUIDE and tel.attitude is not None:
            self._yaw_rad = tel.attitude.yaw_rad
        self._hold = None
        if source is None and tel.pos_vel is not None:
            source = self._hold = FixedPoint("hold", tel.pos_vel.pos_ned_m)
        self._source = source
        self._allow_below_min = allow_below_min
        self.mode = LoopMode.GUIDE
        self._events.write(self._clock.now_s(), "setpoint", decision="engage", source=source.name if source else None)

    def standby(self) -> None:
        self.mode = LoopMode.STANDBY if self._standby_period_s > 0 else LoopMode.OFF
        self._last_send_s = None
        self._source = self._hold = None
        self._events.write(self._clock.now_s(), "setpoint", decision=self.mode.value.lower())

    def disengage(self) -> None:
        if self.mode != LoopMode.OFF:
            self._events.write(self._clock.now_s(), "setpoint", decision="off")
        self.mode = LoopMode.OFF
        self._source = self._hold = None
        self._last_send_s = None

    @property
    def source(self) -> TargetSource | None:
        return self._source

    # ---- the loop -------------------------------------------------------------------------------

    async def run(self) -> None:
        next_s = self._clock.now_s()
        while True:
            next_s += self._period_s
            now_s = self._clock.now_s()
            if next_s < now_s:  # fell behind (slow send): skip, never burst
                next_s = now_s + self._period_s
            await self.tick(now_s)
            await sleep_until(self._clock, next_s)

    async def tick(self, now_s: float) -> None:
        if self.mode == LoopMode.GUIDE and self._boundary.accepts_guidance:
            desired, why = self._guide(now_s)
            clamped = await self._boundary.send_velocity(desired, self._yaw_rad, allow_below_min=self._allow_below_min)
            if clamped is None:
                return
            self._count_sent(now_s)
            self._events.write(
                now_s,
                "setpoint",
                decision=why,
                source=self._source.name if self._source else None,
                vel=list(clamped.vel_ned_mps),
                desired=list(desired),
                limits=list(clamped.limits),
                err_m=self._last_err_m,
            )
        elif self.mode == LoopMode.STANDBY and now_s >= self._next_standby_s:
            self._next_standby_s = now_s + self._standby_period_s
            await self._boundary.send_standby()

    def _guide(self, now_s: float) -> tuple[Vec3, str]:
        """The desired velocity (before the envelope) and why."""
        self._last_err_m = None
        tel = self._boundary.telemetry()
        pv = tel.pos_vel
        if pv is None or now_s - pv.t_s > self._stale_s:
            return (0.0, 0.0, 0.0), "stale_position_zero"
        source = self._source
        if source is not None and pv.t_s != self._last_sample_t_s:
            self._last_sample_t_s = pv.t_s
            source.observe(pv)
        target = source.target_at(now_s) if source is not None else None
        why = "guide"
        if target is None:
            # No fresh estimate: hold the position where it went missing (guidance to a fixed point).
            if self._hold is None:
                self._hold = FixedPoint("hold", pv.pos_ned_m)
                self._events.write(now_s, "setpoint", decision="no_target_hold", hold_ned_m=list(pv.pos_ned_m))
            target, why = self._hold.target_at(now_s), "hold"
        elif self._hold is not None and self._hold is not source:
            self._hold = None
        # Guidance on the position predicted to now (telemetry is a few ms old).
        dt_s = now_s - pv.t_s
        pos_now = (
            pv.pos_ned_m[0] + pv.vel_ned_mps[0] * dt_s,
            pv.pos_ned_m[1] + pv.vel_ned_mps[1] * dt_s,
            pv.pos_ned_m[2] + pv.vel_ned_mps[2] * dt_s,
        )
        self._last_err_m = norm(sub(pos_now, target.pos_ned_m))
        desired = constant_bearing_velocity(
            pos_now, target.pos_ned_m, target.vel_ned_mps, self._guidance, target.acc_ned_mps2
        )
        return desired, why

    def _count_sent(self, now_s: float) -> None:
        self.sent += 1
        if self._last_send_s is not None:
            self.send_intervals_s.append(now_s - self._last_send_s)
        self._last_send_s = now_s

    def interval_summary(self) -> dict[str, float | None]:
        """Spacing of the guidance setpoints actually sent (the loop's period plus whatever delayed it)."""
        xs = sorted(self.send_intervals_s)
        return {
            "setpoint_interval_p50_s": percentile(xs, 0.50),
            "setpoint_interval_p95_s": percentile(xs, 0.95),
            "setpoint_interval_max_s": xs[-1] if xs else None,
        }
