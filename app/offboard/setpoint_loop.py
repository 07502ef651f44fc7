"""The offboard setpoint loop: fixed rate, never silent while the mission has control.

Modes:
- ``GUIDE``: every period, constant-bearing guidance toward the target source (or, with none, the
  position where guidance was engaged), through the envelope, to ``set_velocity_ned``. Stale position
  telemetry → zero velocity (hold) until it is fresh again.
- ``STANDBY``: the pilot has control (PX4): zero-velocity setpoints at a low rate, only so the pilot can
  hand back by selecting OFFBOARD (PX4 refuses OFFBOARD without a setpoint stream; it ignores the stream
  in every other mode). No mode is ever commanded from here.
- ``OFF``: sends nothing.
Every decision is written to the event log.
"""

from __future__ import annotations

import math
from collections import deque
from enum import StrEnum
from typing import Protocol

from app.clock import Clock, sleep_until
from app.errors import VehicleError
from app.eventlog import EventLog
from app.messages import PositionVelocityNed, TargetState, Vec3, norm, sub
from app.offboard.envelope import EnvelopeLimits, apply_envelope
from app.offboard.guidance import ConstantBearingParams, constant_bearing_velocity
from app.offboard.vehicle import Vehicle
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
        vehicle: Vehicle,
        clock: Clock,
        events: EventLog,
        guidance: ConstantBearingParams,
        limits: EnvelopeLimits,
        rate_hz: float,
        standby_rate_hz: float,
        position_stale_s: float,
    ) -> None:
        self._vehicle = vehicle
        self._clock = clock
        self._events = events
        self._guidance = guidance
        self._limits = limits
        self._period_s = 1.0 / rate_hz
        self._standby_period_s = 1.0 / standby_rate_hz if standby_rate_hz > 0 else 0.0
        self._stale_s = position_stale_s
        self.mode = LoopMode.OFF
        self._source: TargetSource | None = None
        self._yaw_rad = 0.0
        self._allow_below_min = False
        self._last_sample_t_s: float | None = None
        self._next_standby_s = 0.0
        self.sent = 0
        self.send_errors = 0
        self._last_send_s: float | None = None
        self.send_intervals_s: deque[float] = deque(maxlen=100_000)  # between guidance setpoints

    # ---- control (called by the mission runner) -------------------------------------------------

    def engage(self, source: TargetSource | None, *, allow_below_min: bool = False) -> None:
        """Start guiding toward ``source``; ``None`` holds the current position."""
        tel = self._vehicle.telemetry()
        if source is None and tel.pos_vel is not None:
            source = FixedPoint("hold", tel.pos_vel.pos_ned_m)
        if self.mode != LoopMode.GUIDE and tel.attitude is not None:
            self._yaw_rad = tel.attitude.yaw_rad
        self._source = source
        self._allow_below_min = allow_below_min
        self.mode = LoopMode.GUIDE
        self._events.write(self._clock.now_s(), "setpoint", decision="engage", source=source.name if source else None)

    def standby(self) -> None:
        self.mode = LoopMode.STANDBY if self._standby_period_s > 0 else LoopMode.OFF
        self._last_send_s = None
        self._source = None
        self._events.write(self._clock.now_s(), "setpoint", decision=self.mode.value.lower())

    def disengage(self) -> None:
        if self.mode != LoopMode.OFF:
            self._events.write(self._clock.now_s(), "setpoint", decision="off")
        self.mode = LoopMode.OFF
        self._source = None
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
        if self.mode == LoopMode.GUIDE:
            vel, yaw = self._guide(now_s)
            await self._send(vel, yaw)
        elif self.mode == LoopMode.STANDBY and now_s >= self._next_standby_s:
            self._next_standby_s = now_s + self._standby_period_s
            await self._send((0.0, 0.0, 0.0), self._yaw_rad)

    def _guide(self, now_s: float) -> tuple[Vec3, float]:
        tel = self._vehicle.telemetry()
        pv = tel.pos_vel
        if pv is None or now_s - pv.t_s > self._stale_s:
            age = None if pv is None else now_s - pv.t_s
            self._events.write(now_s, "setpoint", decision="stale_position_hold", age_s=age, vel=[0.0, 0.0, 0.0])
            return (0.0, 0.0, 0.0), self._yaw_rad
        source = self._source
        if source is not None and pv.t_s != self._last_sample_t_s:
            self._last_sample_t_s = pv.t_s
            source.observe(pv)
        target = source.target_at(now_s) if source is not None else None
        if target is None:
            self._events.write(now_s, "setpoint", decision="no_target_hold", vel=[0.0, 0.0, 0.0])
            return (0.0, 0.0, 0.0), self._yaw_rad
        # Guidance on the position predicted to now (telemetry is a few ms old).
        dt_s = now_s - pv.t_s
        pos_now = (
            pv.pos_ned_m[0] + pv.vel_ned_mps[0] * dt_s,
            pv.pos_ned_m[1] + pv.vel_ned_mps[1] * dt_s,
            pv.pos_ned_m[2] + pv.vel_ned_mps[2] * dt_s,
        )
        desired = constant_bearing_velocity(
            pos_now, target.pos_ned_m, target.vel_ned_mps, self._guidance, target.acc_ned_mps2
        )
        home = tel.home_ned_m or (0.0, 0.0, 0.0)
        clamped = apply_envelope(desired, pv.pos_ned_m, home, self._limits, allow_below_min=self._allow_below_min)
        self._events.write(
            now_s,
            "setpoint",
            decision="guide",
            source=source.name if source else None,
            vel=list(clamped.vel_ned_mps),
            desired=list(desired),
            limits=list(clamped.limits),
            err_m=norm(sub(pos_now, target.pos_ned_m)),
        )
        return clamped.vel_ned_mps, self._yaw_rad

    def interval_summary(self) -> dict[str, float | None]:
        """Spacing of the guidance setpoints actually sent (the loop's period plus whatever delayed it)."""
        xs = sorted(self.send_intervals_s)
        return {
            "setpoint_interval_p50_s": percentile(xs, 0.50),
            "setpoint_interval_p95_s": percentile(xs, 0.95),
            "setpoint_interval_max_s": xs[-1] if xs else None,
        }

    async def _send(self, vel: Vec3, yaw_rad: float) -> None:
        if not all(math.isfinite(v) for v in vel):
            vel = (0.0, 0.0, 0.0)
        try:
            await self._vehicle.set_velocity_ned(vel, yaw_rad)
            self.sent += 1
            now_s = self._clock.now_s()
            if self.mode == LoopMode.GUIDE:
                if self._last_send_s is not None:
                    self.send_intervals_s.append(now_s - self._last_send_s)
                self._last_send_s = now_s
        except VehicleError as e:
            self.send_errors += 1
            self._events.write(self._clock.now_s(), "setpoint", decision="send_failed", error=str(e))
