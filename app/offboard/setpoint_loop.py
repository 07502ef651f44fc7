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

The tick comes first on the event loop: other work there (the estimator's update on a new fix) asks
``make_room(work_s)`` before it starts and, when the next tick is due sooner than that, runs after it — one
synchronous update started 1 ms before the tick delays it by the update's length (real flights: 2–4 ms).
"""

from __future__ import annotations

import asyncio
import math
from collections import deque
from enum import StrEnum
from typing import Protocol

from app.clock import Clock, sleep_until
from app.eventlog import EventLog
from app.messages import PositionVelocityNed, TargetState, Vec3, norm, sub
from app.offboard.boundary import VehicleBoundary
from app.offboard.guidance import ConstantBearingParams, PositionIntegral, constant_bearing_velocity
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
        self._integral = PositionIntegral(guidance)
        self._integral_source: object | None = None  # the target the integral was built on
        self._integral_t_s: float | None = None
        self._last_saturated = False
        self._prev_sample: PositionVelocityNed | None = None
        self.inconsistency_ned_mps: Vec3 = (0.0, 0.0, 0.0)  # d̂: how the reported position outruns v̂
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
        self.wake_late_s: deque[float] = deque(maxlen=100_000)  # each guidance tick: how late it woke
        self._next_tick_s: float | None = None  # while running: when the next tick is due
        self._tick_waiters: list[asyncio.Future[None]] = []  # ``make_room`` callers waiting for that tick

    @property
    def period_s(self) -> float:
        return self._period_s

    # ---- control (called by the mission runner) -------------------------------------------------

    def engage(
        self, source: TargetSource | None, *, allow_below_min: bool = False, keep_integral: bool = False
    ) -> None:
        """Start guiding toward ``source``; ``None`` holds the current position. ``keep_integral``: ``source``
        follows the same target as the source it replaces (GRAB's sink after DESCEND, both over the object): the
        integral term built on that one carries on rather than restarting at zero."""
        tel = self._boundary.telemetry()
        if self.mode != LoopMode.GUIDE and tel.attitude is not None:
            self._yaw_rad = tel.attitude.yaw_rad
        self._hold = None
        if source is None and tel.pos_vel is not None:
            source = self._hold = FixedPoint("hold", tel.pos_vel.pos_ned_m)
        carry_on = keep_integral and self.mode == LoopMode.GUIDE and self._integral_source is self._source
        self._source = source
        if carry_on and source is not None:
            self._integral_source = source
        else:
            self._reset_integral(None)
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
        try:
            while True:
                due_s, next_s = next_s, next_s + self._period_s
                now_s = self._clock.now_s()
                if next_s < now_s:  # fell behind (slow send): skip, never burst
                    next_s = now_s + self._period_s
                if self.mode == LoopMode.GUIDE:
                    self.wake_late_s.append(max(0.0, now_s - due_s))
                await self.tick(now_s)
                self._next_tick_s = next_s
                self._release_waiters()
                await sleep_until(self._clock, next_s)
        finally:
            self._next_tick_s = None
            self._release_waiters()

    async def make_room(self, work_s: float) -> None:
        """Return when ``work_s`` of synchronous work on the event loop would not delay the next tick: at once
        when the tick is further away than that (or the loop is not running, or ``work_s`` is 0, as in virtual
        time, where work takes none), else once that tick has run (at most one period on)."""
        next_s = self._next_tick_s
        if work_s <= 0.0 or next_s is None or next_s - self._clock.now_s() > work_s:
            return
        waiter = asyncio.get_running_loop().create_future()
        self._tick_waiters.append(waiter)
        try:
            async with asyncio.timeout(self._period_s + work_s):
                await waiter
        except TimeoutError:
            pass

    def _release_waiters(self) -> None:
        waiters, self._tick_waiters = self._tick_waiters, []
        for w in waiters:
            if not w.done():
                w.set_result(None)

    async def tick(self, now_s: float) -> None:
        if self.mode == LoopMode.GUIDE and self._boundary.accepts_guidance:
            desired, why = self._guide(now_s)
            clamped = await self._boundary.send_velocity(desired, self._yaw_rad, allow_below_min=self._allow_below_min)
            if clamped is None:
                return
            self._last_saturated = bool(clamped.limits)
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
            self._reset_integral(None)
            return (0.0, 0.0, 0.0), "stale_position_zero"
        source = self._source
        if pv.t_s != self._last_sample_t_s:
            self._last_sample_t_s = pv.t_s
            self._observe_inconsistency(pv)
            if source is not None:
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
        if target.yaw_rad is not None:
            self._yaw_rad = target.yaw_rad
        # Guidance on the position predicted to now (telemetry is a few ms old).
        dt_s = now_s - pv.t_s
        pos_now = (
            pv.pos_ned_m[0] + pv.vel_ned_mps[0] * dt_s,
            pv.pos_ned_m[1] + pv.vel_ned_mps[1] * dt_s,
            pv.pos_ned_m[2] + pv.vel_ned_mps[2] * dt_s,
        )
        pos_err = sub(pos_now, target.pos_ned_m)
        self._last_err_m = norm(pos_err)
        params = self._guidance.for_target(target.precise)
        desired = constant_bearing_velocity(
            pos_now, target.pos_ned_m, target.vel_ned_mps, params, target.acc_ned_mps2, pv.vel_ned_mps
        )
        v_i = self._integrate(now_s, self._hold if why == "hold" else source, pos_err)
        d = self.inconsistency_ned_mps
        vn, ve, vd = desired[0] + v_i[0] - d[0], desired[1] + v_i[1] - d[1], desired[2] + v_i[2] - d[2]
        # Horizontal velocity-error feedback: v_sp + K_v (v_sp − v̂), its norm bounded (see guidance).
        kv, v = params.velocity_error_gain, pv.vel_ned_mps
        fn, fe = kv * (vn - v[0]), kv * (ve - v[1])
        f_max, f = params.velocity_error_max_mps, math.hypot(fn, fe)
        if f > f_max:
            fn, fe = fn * f_max / f, fe * f_max / f
        return (vn + fn, ve + fe, vd), why

    def _observe_inconsistency(self, pv: PositionVelocityNed) -> None:
        """d̂ = low-pass(dp̂/dt − v̂): the autopilot steers its velocity *estimate* to our setpoint, so when
        its estimate is off, the reported position moves at v_sp + d̂; sending v_sp − d̂ cancels that."""
        prev, self._prev_sample = self._prev_sample, pv
        tau_s = self._guidance.inconsistency_tau_s
        if tau_s <= 0.0 or prev is None:
            return
        dt_s = pv.t_s - prev.t_s
        if not 0.0 < dt_s <= 0.2:  # a gap: start over
            self.inconsistency_ned_mps = (0.0, 0.0, 0.0)
            return
        k = 1.0 - math.exp(-dt_s / tau_s)
        d = self.inconsistency_ned_mps
        raw = [
            (pv.pos_ned_m[i] - prev.pos_ned_m[i]) / dt_s - 0.5 * (pv.vel_ned_mps[i] + prev.vel_ned_mps[i])
            for i in range(3)
        ]
        lim = self._guidance.inconsistency_max_mps
        self.inconsistency_ned_mps = (
            max(-lim, min(lim, d[0] + k * (raw[0] - d[0]))),
            max(-lim, min(lim, d[1] + k * (raw[1] - d[1]))),
            max(-lim, min(lim, d[2] + k * (raw[2] - d[2]))),
        )

    def _integrate(self, now_s: float, target_source: object | None, pos_err: Vec3) -> Vec3:
        """The position loop's integral term: restarts with every new target source."""
        if target_source is not self._integral_source:
            self._reset_integral(target_source)
        dt_s = now_s - self._integral_t_s if self._integral_t_s is not None else 0.0
        self._integral_t_s = now_s
        return self._integral.update(pos_err, dt_s, saturated=self._last_saturated)

    def _reset_integral(self, target_source: object | None) -> None:
        self._integral.reset()
        self._integral_source = target_source
        self._integral_t_s = None
        self._last_saturated = False

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
            "setpoint_interval_p99_s": percentile(xs, 0.99),
            "setpoint_interval_max_s": xs[-1] if xs else None,
            "setpoint_wake_late_p99_s": percentile(sorted(self.wake_late_s), 0.99),
            "setpoint_wake_late_max_s": max(self.wake_late_s, default=None),
        }
