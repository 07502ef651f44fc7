"""The setpoint loop's compensation terms (issue 10): what goes out for a given telemetry stream.

The boundary here is a stand-in that records what the loop asks to send (the real boundary and its envelope
are covered by the mission tests); telemetry is scripted so the expected setpoint can be worked by hand.
"""

from __future__ import annotations

import pytest

from app.clock import Clock
from app.eventlog import EventLog
from app.messages import PositionVelocityNed, TargetState, TelemetrySnapshot
from app.offboard.envelope import Clamped
from app.offboard.guidance import ConstantBearingParams
from app.offboard.setpoint_loop import SetpointLoop


class ScriptedClock(Clock):
    def __init__(self) -> None:
        self.t_s = 0.0

    def now_s(self) -> float:
        return self.t_s


class RecordingBoundary:
    accepts_guidance = True

    def __init__(self) -> None:
        self.sample = PositionVelocityNed(0.0, (0.0, 0.0, -5.0), (0.0, 0.0, 0.0))
        self.sent: list[tuple[float, float, float]] = []

    def telemetry(self) -> TelemetrySnapshot:
        return TelemetrySnapshot(pos_vel=self.sample)

    async def send_velocity(self, vel, yaw_rad, *, allow_below_min=False):
        self.sent.append(tuple(vel))
        return Clamped(tuple(vel), ())


class Follow:
    """A target that sits exactly where the vehicle reports itself: no position error, no integral."""

    name = "follow"

    def __init__(self, boundary: RecordingBoundary) -> None:
        self.b = boundary

    def target_at(self, t_s):
        return TargetState(t_s, self.b.sample.pos_ned_m, (0.0, 0.0, 0.0))

    def observe(self, sample):
        pass


class Fixed:
    name = "fixed"

    def __init__(self, pos, precise=False):
        self.pos, self.precise = pos, precise

    def target_at(self, t_s):
        return TargetState(t_s, self.pos, (0.0, 0.0, 0.0), precise=self.precise)

    def observe(self, sample):
        pass


def make_loop(**params):
    clock, boundary = ScriptedClock(), RecordingBoundary()
    guidance = ConstantBearingParams(2.0, 0.4, **params)
    loop = SetpointLoop(boundary, clock, EventLog(None), guidance, 50.0, 5.0, 0.5)  # type: ignore[arg-type]
    return loop, clock, boundary


async def run_ticks(loop, clock, boundary, n, step):
    for _ in range(n):
        clock.t_s += 0.02
        boundary.sample = step(clock.t_s, boundary.sample)
        await loop.tick(clock.t_s)


async def test_observer_cancels_a_position_that_outruns_the_reported_velocity():
    """The autopilot reports v̂ = 0 while its position estimate moves north at 0.3 m/s: the loop learns
    d̂ = +0.3 m/s north and sends −0.3 m/s to cancel it."""
    loop, clock, boundary = make_loop(inconsistency_tau_s=0.2)
    loop.engage(Follow(boundary))

    def drift(t_s, s):
        return PositionVelocityNed(t_s, (s.pos_ned_m[0] + 0.3 * 0.02, 0.0, -5.0), (0.0, 0.0, 0.0))

    await run_ticks(loop, clock, boundary, 100, drift)  # 2 s = 10 τ
    assert loop.inconsistency_ned_mps[0] == pytest.approx(0.3, abs=1e-3)
    assert boundary.sent[-1] == pytest.approx((-0.3, 0.0, 0.0), abs=1e-3)


async def test_without_the_observer_the_same_stream_sends_nothing():
    loop, clock, boundary = make_loop()
    loop.engage(Follow(boundary))

    def drift(t_s, s):
        return PositionVelocityNed(t_s, (s.pos_ned_m[0] + 0.3 * 0.02, 0.0, -5.0), (0.0, 0.0, 0.0))

    await run_ticks(loop, clock, boundary, 100, drift)
    assert boundary.sent[-1] == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)


async def test_integral_builds_on_a_standing_error_and_restarts_on_engage():
    loop, clock, boundary = make_loop(integral_gain_per_s2=3.0)
    target = Fixed((0.1, 0.0, -5.0))  # the vehicle stays 0.1 m south of it
    loop.engage(target)

    def still(t_s, s):
        return PositionVelocityNed(t_s, (0.0, 0.0, -5.0), (0.0, 0.0, 0.0))

    await run_ticks(loop, clock, boundary, 50, still)  # 1 s
    p_term = 2.0 * 0.1 / (0.1**2 + 0.4**2) ** 0.5  # constant bearing κ at 0.1 m
    assert boundary.sent[-1][0] == pytest.approx(p_term + 3.0 * 0.1 * 0.98, abs=0.01)  # 49 steps of K_I·e·dt
    loop.disengage()
    loop.engage(target)
    await run_ticks(loop, clock, boundary, 1, still)
    assert boundary.sent[-1][0] == pytest.approx(p_term, abs=1e-9)  # a new engagement starts from zero


async def test_velocity_error_feedback_is_horizontal_and_bounded():
    loop, clock, boundary = make_loop(velocity_error_gain=2.0, velocity_error_max_mps=1.0)
    loop.engage(Follow(boundary))

    def slow(t_s, s):  # reported velocity 0.2 m/s south, 0.3 m/s down, where guidance wants 0
        return PositionVelocityNed(t_s, s.pos_ned_m, (-0.2, 0.0, 0.3))

    await run_ticks(loop, clock, boundary, 1, slow)
    assert boundary.sent[-1] == pytest.approx((0.4, 0.0, 0.0))  # 2·(0 − (−0.2)); nothing vertically

    def fast(t_s, s):
        return PositionVelocityNed(t_s, s.pos_ned_m, (-3.0, 4.0, 0.0))

    await run_ticks(loop, clock, boundary, 1, fast)
    assert boundary.sent[-1] == pytest.approx((0.6, -0.8, 0.0))  # ‖2·(3, −4)‖ = 10 → bounded to 1 m/s


@pytest.mark.parametrize(("precise", "sent"), [(False, (0.6, -0.8, 0.0)), (True, (1.8, -2.4, 0.0))])
async def test_a_precise_target_gets_the_precise_velocity_error_bound(precise, sent):
    """The same velocity error as above (‖2·(3, −4)‖ = 10 m/s): bounded to 1 m/s, or to 3 m/s when the target
    asks for precision (going down onto the object the 1 m/s bound clipped the feedback in the descent's swing)."""
    loop, clock, boundary = make_loop(
        velocity_error_gain=2.0, velocity_error_max_mps=1.0, precise_velocity_error_max_mps=3.0
    )

    class Precise(Follow):
        def target_at(self, t_s):
            return TargetState(t_s, self.b.sample.pos_ned_m, (0.0, 0.0, 0.0), precise=precise)

    loop.engage(Precise(boundary))
    await run_ticks(loop, clock, boundary, 1, lambda t_s, s: PositionVelocityNed(t_s, s.pos_ned_m, (-3.0, 4.0, 0.0)))
    assert boundary.sent[-1] == pytest.approx(sent)


@pytest.mark.parametrize(("precise", "north_mps"), [(False, 0.4851), (True, 0.7428)])
async def test_a_precise_target_gets_the_precise_transient_distance(precise, north_mps):
    """0.1 m short of a still target: κ = U·0.1/√(0.1² + Δ²) with Δ 0.4 m, or 0.25 m when the target asks for
    precision (the pickup going down onto the object)."""
    loop, clock, boundary = make_loop(precise_transient_distance_m=0.25)
    loop.engage(Fixed((0.1, 0.0, -5.0), precise))
    await run_ticks(
        loop, clock, boundary, 1, lambda t_s, s: PositionVelocityNed(t_s, (0.0, 0.0, -5.0), (0.0, 0.0, 0.0))
    )
    assert boundary.sent[-1][0] == pytest.approx(north_mps, abs=1e-4) and boundary.sent[-1][1:] == (0.0, 0.0)


@pytest.mark.parametrize(("precise", "north_mps"), [(False, -0.4851), (True, -0.2481)])
async def test_a_precise_target_is_damped_by_the_vehicle_velocity(precise, north_mps):
    """0.1 m north of a still target, closing at 0.5 m/s: Δ 0.4 m gives κ = 2·0.1/√(0.1² + 0.4²); a precise target
    with τ_d 0.1 s sees the error 0.05 m ahead (2·0.05/√(0.05² + 0.4²)), from the telemetry's velocity."""
    loop, clock, boundary = make_loop(precise_damping_s=0.1)
    loop.engage(Fixed((0.0, 0.0, -5.0), precise))
    await run_ticks(
        loop, clock, boundary, 1, lambda t_s, s: PositionVelocityNed(t_s, (0.1, 0.0, -5.0), (-0.5, 0.0, 0.0))
    )
    assert boundary.sent[-1][0] == pytest.approx(north_mps, abs=1e-4) and boundary.sent[-1][1:] == (0.0, 0.0)


async def test_a_source_following_the_same_target_keeps_the_integral_only_when_asked():
    """GRAB's sink takes over from DESCEND over the same object: with ``keep_integral`` the integral built on the
    standing error carries on; a plain engage (or one from a hold) restarts it at zero."""
    still = lambda t_s, s: PositionVelocityNed(t_s, (0.0, 0.0, -5.0), (0.0, 0.0, 0.0))  # noqa: E731
    p_term = 2.0 * 0.1 / (0.1**2 + 0.4**2) ** 0.5
    built = 3.0 * 0.1 * 0.98  # 49 steps of K_I·e·dt
    for keep, expected in ((True, p_term + built + 3.0 * 0.1 * 0.02), (False, p_term)):
        loop, clock, boundary = make_loop(integral_gain_per_s2=3.0)
        loop.engage(Fixed((0.1, 0.0, -5.0)))
        await run_ticks(loop, clock, boundary, 50, still)
        assert boundary.sent[-1][0] == pytest.approx(p_term + built, abs=0.01)
        loop.engage(Fixed((0.1, 0.0, -5.0)), keep_integral=keep)
        await run_ticks(loop, clock, boundary, 1, still)
        assert boundary.sent[-1][0] == pytest.approx(expected, abs=0.01), keep
    loop.disengage()  # not guiding: nothing to carry on
    loop.engage(Fixed((0.1, 0.0, -5.0)), keep_integral=True)
    await run_ticks(loop, clock, boundary, 1, still)
    assert boundary.sent[-1][0] == pytest.approx(p_term, abs=1e-9)


@pytest.mark.parametrize(("precise", "north_mps"), [(False, 0.7), (True, 0.4)])
async def test_a_precise_target_gets_the_precise_lead(precise, north_mps):
    """On a still vehicle right on a target accelerating north at 1 m/s²: the feed-forward is τ_lead·a_t, with the
    autopilot's lead (0.7 s) or, for a target that asks for precision, the precise one (0.4 s)."""
    loop, clock, boundary = make_loop(velocity_lead_s=0.7, precise_velocity_lead_s=0.4)

    class Accelerating(Fixed):
        def target_at(self, t_s):
            return TargetState(t_s, self.pos, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), precise=precise)

    loop.engage(Accelerating((0.0, 0.0, -5.0)))
    await run_ticks(
        loop, clock, boundary, 1, lambda t_s, s: PositionVelocityNed(t_s, (0.0, 0.0, -5.0), (0.0, 0.0, 0.0))
    )
    assert boundary.sent[-1] == pytest.approx((north_mps, 0.0, 0.0), abs=1e-9)
