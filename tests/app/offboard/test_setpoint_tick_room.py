"""The setpoint tick comes first on the event loop: work that would start too close before it waits until it has run.

In virtual time (looptime) the loop's clock is exact, so the tests place the work's start at chosen phases of the
50 Hz tick and read, from the loop's own counters, whether it ran before or after the tick.
"""

from __future__ import annotations

import asyncio

import pytest

from app.clock import LoopClock, PreciseClock
from app.eventlog import EventLog
from app.messages import PositionVelocityNed, TargetState, TelemetrySnapshot
from app.missions.pickup_feeds import HeightSample, PickupFeeds
from app.offboard.envelope import Clamped
from app.offboard.guidance import ConstantBearingParams
from app.offboard.setpoint_loop import SetpointLoop

LOOPTIME = pytest.mark.looptime(noop_cycles=2)
PERIOD_S = 0.02


class Boundary:
    accepts_guidance = True

    def __init__(self) -> None:
        self.sent_at: list[float] = []

    def telemetry(self) -> TelemetrySnapshot:
        return TelemetrySnapshot(pos_vel=PositionVelocityNed(asyncio.get_running_loop().time(), (0.0, 0.0, -5.0),
                                                             (0.0, 0.0, 0.0)))  # fmt: skip

    async def send_velocity(self, vel, yaw_rad, *, allow_below_min=False):
        self.sent_at.append(asyncio.get_running_loop().time())
        return Clamped(tuple(vel), ())


class Still:
    name = "still"

    def target_at(self, t_s):
        return TargetState(t_s, (0.0, 0.0, -5.0), (0.0, 0.0, 0.0))

    def observe(self, sample):
        pass


def make_loop() -> tuple[SetpointLoop, Boundary, LoopClock]:
    clock, boundary = LoopClock(), Boundary()
    loop = SetpointLoop(boundary, clock, EventLog(None), ConstantBearingParams(2.0, 0.4), 1.0 / PERIOD_S, 5.0, 0.5)  # type: ignore[arg-type]
    loop.engage(Still())
    return loop, boundary, clock


@LOOPTIME
async def test_work_close_before_the_tick_waits_for_it_and_work_with_room_goes_at_once():
    loop, boundary, clock = make_loop()
    task = asyncio.create_task(loop.run())
    try:
        await clock.sleep(0.1)  # the loop is ticking: the first tick was at 0, the next ones every 20 ms
        t0_s = clock.now_s()
        first_tick_s = boundary.sent_at[0]
        due_s = first_tick_s + PERIOD_S * (round((t0_s - first_tick_s) / PERIOD_S) + 1)
        assert due_s > t0_s

        # 10 ms before the tick, 5 ms of work fits: it goes at once, the tick still to come
        await clock.sleep(due_s - 0.010 - clock.now_s())
        sent = len(boundary.sent_at)
        start_s = clock.now_s()
        await loop.make_room(0.005)
        assert clock.now_s() == pytest.approx(start_s, abs=1e-9)
        assert len(boundary.sent_at) == sent

        # 3 ms before it, 5 ms of work would delay it: the work waits until the tick has gone out
        await clock.sleep(due_s - 0.003 - clock.now_s())
        sent = len(boundary.sent_at)
        await loop.make_room(0.005)
        assert len(boundary.sent_at) == sent + 1
        assert boundary.sent_at[-1] == pytest.approx(due_s, abs=1e-6)  # the tick went out on time
        assert clock.now_s() == pytest.approx(due_s, abs=1e-6)  # and the work right after it

        # no margin (virtual time's: work takes no time there): at once, whatever the phase
        await clock.sleep(due_s + PERIOD_S - 0.001 - clock.now_s())
        sent = len(boundary.sent_at)
        await loop.make_room(0.0)
        assert len(boundary.sent_at) == sent
        assert loop.wake_late_s and max(loop.wake_late_s) == 0.0
    finally:
        task.cancel()


@LOOPTIME
async def test_a_waiter_is_let_go_when_the_loop_stops_or_does_not_run():
    loop, boundary, clock = make_loop()
    await asyncio.wait_for(loop.make_room(0.005), 0.001)  # not running: nothing to wait for
    task = asyncio.create_task(loop.run())
    await clock.sleep(0.019)  # 1 ms before the second tick
    waiter = asyncio.create_task(loop.make_room(0.005))
    await asyncio.sleep(0)
    task.cancel()  # the loop ends before that tick
    with pytest.raises(asyncio.CancelledError):
        await task
    await asyncio.wait_for(waiter, 0.001)  # released by the loop's end, not by its timeout
    assert len(boundary.sent_at) == 1


@LOOPTIME
async def test_the_estimators_consumers_ask_for_room_before_each_update():
    loop, boundary, clock = make_loop()
    task = asyncio.create_task(loop.run())

    class Model:
        def __init__(self) -> None:
            self.updates: list[tuple[float, int]] = []  # (loop time, setpoints sent before it)

        def on_height(self, t_s: float, height_m: float) -> None:
            self.updates.append((clock.now_s(), len(boundary.sent_at)))

        def on_radar_lost(self) -> None:
            raise AssertionError("not lost")

    model = Model()
    feeds = PickupFeeds(make_room=lambda: loop.make_room(0.005))
    consumer = asyncio.create_task(feeds.consume_heights(model))  # type: ignore[arg-type]
    try:
        await clock.sleep(0.038)  # 2 ms before the tick at 40 ms
        feeds.heights.put(HeightSample(clock.now_s(), 3.0))
        await clock.sleep(0.010)  # 48 ms: 12 ms of room
        feeds.heights.put(HeightSample(clock.now_s(), 3.1))
        await clock.sleep(0.005)
        assert model.updates[0] == (pytest.approx(0.040, abs=1e-6), 3)  # after the ticks at 0, 20 and 40 ms
        assert model.updates[1] == (pytest.approx(0.048, abs=1e-6), 3)  # at once
    finally:
        consumer.cancel()
        task.cancel()


def test_only_real_time_keeps_a_margin():
    assert LoopClock.work_margin_s == 0.0  # virtual time: work takes none, and runs are as before
    assert PreciseClock.work_margin_s > 0.0
