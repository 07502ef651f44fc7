"""The one clock of the app: the asyncio loop's time.

Nothing in ``app/`` reads ``time.time()`` or ``time.monotonic()``; everything asks a ``Clock``. In tests
the loop's time is virtual (looptime), so whole missions run in milliseconds.
"""

from __future__ import annotations

import asyncio
import contextlib
import heapq
import itertools
import threading
from typing import Protocol


class Clock(Protocol):
    def now_s(self) -> float:
        """Seconds on the loop clock (arbitrary epoch, monotonic)."""
        ...

    async def sleep(self, dt_s: float) -> None:
        """Sleep ``dt_s`` seconds of loop time."""
        ...


class LoopClock:
    """The running asyncio loop's clock (virtual under looptime)."""

    def now_s(self) -> float:
        return asyncio.get_running_loop().time()

    async def sleep(self, dt_s: float) -> None:
        await asyncio.sleep(max(0.0, dt_s))


async def sleep_until(clock: Clock, t_s: float) -> None:
    """Sleep until loop time ``t_s`` (returns at once when it has passed)."""
    await clock.sleep(t_s - clock.now_s())


class PreciseClock(LoopClock):
    """The loop's clock, with wakes that land on time: for the 50 Hz setpoint loop in real time only.

    asyncio's selector rounds every timeout *up* to whole milliseconds (epoll), so a timer-driven wake comes
    0–1 ms late — a tenth of the setpoint period's jitter budget. Here a timer thread waits for the deadline
    on a monotonic condition variable (microseconds) and wakes the loop through its self-pipe, which epoll
    reports at once. The thread reads only the loop's clock. Not for virtual time: under looptime the loop's
    time is not the thread's.
    """

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._pending: list[tuple[float, int, asyncio.Future[None], asyncio.AbstractEventLoop]] = []
        self._count = itertools.count()
        self._thread: threading.Thread | None = None

    async def sleep(self, dt_s: float) -> None:
        if dt_s <= 0.0:
            await asyncio.sleep(0)
            return
        loop = asyncio.get_running_loop()
        fut: asyncio.Future[None] = loop.create_future()
        with self._cond:
            heapq.heappush(self._pending, (loop.time() + dt_s, next(self._count), fut, loop))
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name="clock.precise", daemon=True)
                self._thread.start()
            self._cond.notify()
        await fut  # cancelling it is enough: the thread then skips it

    def _run(self) -> None:
        with self._cond:
            while True:
                if not self._pending:
                    self._cond.wait()
                    continue
                deadline_s, _, fut, loop = self._pending[0]
                remaining_s = deadline_s - loop.time()
                if remaining_s > 0.0:
                    self._cond.wait(remaining_s)
                    continue
                heapq.heappop(self._pending)
                with contextlib.suppress(RuntimeError):  # the loop has closed
                    loop.call_soon_threadsafe(_wake, fut)


def _wake(fut: asyncio.Future[None]) -> None:
    if not fut.done():
        fut.set_result(None)
