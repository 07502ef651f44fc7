"""``PreciseClock``: real-time sleeps woken by a timerfd instead of epoll's whole-millisecond timeout;
``realtime_thread``: the event loop's thread under SCHED_FIFO, the threads it starts not."""

from __future__ import annotations

import asyncio
import os
import statistics
import subprocess
import sys
import threading

import pytest

from app.clock import LoopClock, PreciseClock, realtime_thread, sleep_until


async def _lateness_ms(clock, n: int = 40, period_s: float = 0.02) -> list[float]:
    """Sleep to ``n`` deadlines a period apart (as the setpoint loop does); how late each wake was, ms."""
    loop = asyncio.get_running_loop()
    next_s = loop.time()
    late = []
    for _ in range(n):
        next_s += period_s
        await sleep_until(clock, next_s)
        late.append((loop.time() - next_s) * 1e3)
    return late


async def test_wakes_are_never_early_and_print_how_late_they_are_against_the_loops_own_timer():
    precise, plain = await _lateness_ms(PreciseClock()), await _lateness_ms(LoopClock())
    print(
        f"lateness median / max, ms: precise {statistics.median(precise):.3f} / {max(precise):.3f}, "
        f"asyncio {statistics.median(plain):.3f} / {max(plain):.3f}"
    )
    assert min(precise) >= 0.0 and min(plain) >= -0.001  # asyncio may wake within its clock resolution
    assert max(precise) < 50.0  # generous: a loaded 2-core machine


async def test_sleepers_wake_in_deadline_order_and_a_cancelled_one_never_does():
    clock = PreciseClock()
    woke: list[str] = []

    async def sleeper(name: str, dt_s: float) -> None:
        await clock.sleep(dt_s)
        woke.append(name)

    tasks = [asyncio.create_task(sleeper(n, dt)) for n, dt in (("c", 0.06), ("a", 0.02), ("x", 0.03), ("b", 0.04))]
    await asyncio.sleep(0.005)
    tasks[2].cancel()
    await asyncio.gather(*tasks, return_exceptions=True)
    await asyncio.sleep(0.05)
    assert woke == ["a", "b", "c"] and tasks[2].cancelled()


async def test_a_zero_or_past_sleep_returns_at_once():
    clock = PreciseClock()
    loop = asyncio.get_running_loop()
    t0 = loop.time()
    await clock.sleep(0.0)
    await clock.sleep(-1.0)
    assert loop.time() - t0 < 0.5


@pytest.mark.parametrize("dt_s", [0.001, 0.013])
async def test_it_sleeps_at_least_as_long_as_asked(dt_s):
    clock = PreciseClock()
    loop = asyncio.get_running_loop()
    t0 = loop.time()
    await clock.sleep(dt_s)
    assert loop.time() - t0 >= dt_s


async def test_no_thread_is_started_and_close_releases_the_timer():
    clock = PreciseClock()
    before = threading.active_count()
    await clock.sleep(0.002)
    await clock.sleep(0.002)
    assert threading.active_count() == before  # the kernel wakes the loop: no timer thread
    fd = clock._fd
    assert fd >= 0 and os.readlink(f"/proc/self/fd/{fd}") == "anon_inode:[timerfd]"
    clock.close()
    with pytest.raises(FileNotFoundError):  # closed
        os.readlink(f"/proc/self/fd/{fd}")
    await clock.sleep(0.002)  # usable again: a new timer
    clock.close()


def test_the_loop_thread_runs_sched_fifo_inside_the_block_and_threads_it_starts_do_not():
    seen: dict[str, int] = {}

    def worker() -> None:
        seen["thread"] = os.sched_getscheduler(0)

    with realtime_thread(10) as policy:
        inside = os.sched_getscheduler(0) & ~os.SCHED_RESET_ON_FORK
        t = threading.Thread(target=worker)
        t.start()
        t.join()
        child = subprocess.run(
            [sys.executable, "-c", "import os; print(os.sched_getscheduler(0))"], capture_output=True, text=True
        )
    print(f"policy: {policy}")
    if policy.startswith("normal"):  # refused on this machine: nothing changed
        assert "refused" in policy and inside == os.SCHED_OTHER
    else:
        assert policy == "SCHED_FIFO 10" and inside == os.SCHED_FIFO
    assert seen["thread"] == os.SCHED_OTHER and int(child.stdout) == os.SCHED_OTHER
    assert os.sched_getscheduler(0) == os.SCHED_OTHER  # and back to normal after it


def test_priority_zero_changes_nothing():
    with realtime_thread(0) as policy:
        assert policy == "normal" and os.sched_getscheduler(0) == os.SCHED_OTHER


def test_refused_it_says_so_and_the_thread_stays_at_normal_scheduling():
    with realtime_thread(100) as policy:  # above SCHED_FIFO's 99: the kernel refuses it, as it does without privilege
        assert policy.startswith("normal (SCHED_FIFO 100 refused: ") and os.sched_getscheduler(0) == os.SCHED_OTHER
    assert os.sched_getscheduler(0) == os.SCHED_OTHER


def test_a_clock_bound_to_its_loop_tells_and_sleeps_as_asyncio_does_wake_for_wake() -> None:
    """``LoopClock(loop)`` (an evaluation run's clock) reads that loop's time and sleeps on it without asking asyncio
    for the running loop: the same timers, so sleepers on it and on ``asyncio.sleep`` wake in the same order, at the
    same instants (virtual time), and a cancelled sleep leaves no timer behind."""
    from sim.virtual_loop import VirtualTimeLoop

    def wakes(bound: bool) -> tuple[list[tuple[str, float]], int]:
        loop = VirtualTimeLoop()
        clock = LoopClock(loop if bound else None)
        woke: list[tuple[str, float]] = []

        async def sleeper(name: str, dts: list[float], on_clock: bool) -> None:
            for dt in dts:
                await (clock.sleep(dt) if on_clock else asyncio.sleep(dt))
                woke.append((name, clock.now_s()))

        async def main() -> int:
            tasks = [
                asyncio.create_task(sleeper("clock", [0.02, 0.03, 0.0, 0.05], True)),
                asyncio.create_task(sleeper("asyncio", [0.02, 0.03, 0.0, 0.05], False)),
                asyncio.create_task(sleeper("clock-late", [0.05, 0.05], True)),
                asyncio.create_task(sleeper("cancelled", [0.5], True)),
            ]
            await asyncio.sleep(0.01)
            tasks[3].cancel()
            await asyncio.gather(*tasks, return_exceptions=True)
            return len(loop._scheduled) - sum(h.cancelled() for h in loop._scheduled)  # timers still live

        try:
            live = loop.run_until_complete(main())
        finally:
            loop.close()
        return woke, live

    bound, live = wakes(True)
    assert bound == wakes(False)[0] and live == 0
    assert [t for n, t in bound if n == "clock"] == [t for n, t in bound if n == "asyncio"]
    assert [t for n, t in bound if n == "clock"] == pytest.approx([0.02, 0.05, 0.05, 0.1])
    assert [t for n, t in bound if n == "clock-late"] == pytest.approx([0.05, 0.1])
    assert "cancelled" not in dict(bound)
