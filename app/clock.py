"""The one clock of the app: the asyncio loop's time.

Nothing in ``app/`` reads ``time.time()`` or ``time.monotonic()``; everything asks a ``Clock``. In tests
the loop's time is virtual (looptime), so whole missions run in milliseconds.
"""

from __future__ import annotations

import asyncio
import contextlib
import ctypes
import heapq
import itertools
import math
import os
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Protocol


class Clock(Protocol):
    def now_s(self) -> float:
        """Seconds on the loop clock (arbitrary epoch, monotonic)."""
        ...

    async def sleep(self, dt_s: float) -> None:
        """Sleep ``dt_s`` seconds of loop time."""
        ...


class LoopClock:
    """The running asyncio loop's clock (virtual under looptime).

    ``loop``: the one loop this clock will ever run on (an evaluation run's own loop), read directly instead of
    asking asyncio for the running loop at every call — which on Linux costs a ``getpid`` system call (CPython
    checks for a fork), ~4 % of an in-process run's CPU. Its sleeps are ``asyncio.sleep``'s, step for step: the
    same timer at the same instant, so the same order of wakes."""

    # How long one synchronous step of work on the loop may take, in this clock's time: under virtual time work
    # takes none. The setpoint loop keeps this much clear before its tick (``SetpointLoop.make_room``).
    work_margin_s = 0.0

    def __init__(self, loop: asyncio.AbstractEventLoop | None = None) -> None:
        self._bound = loop

    def now_s(self) -> float:
        return (self._bound or asyncio.get_running_loop()).time()

    async def sleep(self, dt_s: float) -> None:
        if self._bound is None or dt_s <= 0.0:
            await asyncio.sleep(max(0.0, dt_s))
        else:
            await sleep_on(self._bound, dt_s)


async def sleep_on(loop: asyncio.AbstractEventLoop, delay_s: float) -> None:
    """``asyncio.sleep(delay_s)`` (``delay_s`` > 0) on ``loop``, which must be the running one: the same future and
    timer, without looking the running loop up (see ``LoopClock``)."""
    future = loop.create_future()
    handle = loop.call_later(delay_s, _wake, future)
    try:
        await future
    finally:
        handle.cancel()


def _wake(future: asyncio.Future[None]) -> None:
    if not future.cancelled():
        future.set_result(None)


async def sleep_until(clock: Clock, t_s: float) -> None:
    """Sleep until loop time ``t_s`` (returns at once when it has passed)."""
    await clock.sleep(t_s - clock.now_s())


class PreciseClock(LoopClock):
    """The loop's clock, with wakes that land on time: for the 50 Hz setpoint loop in real time only.

    asyncio's selector rounds every timeout *up* to whole milliseconds (epoll), so a timer-driven wake comes
    0–1 ms late — a tenth of the setpoint period's jitter budget. Here the kernel wakes the loop itself: one
    timerfd (Linux), armed for the earliest deadline on the monotonic clock the loop reads, with nanosecond
    resolution, is one more file the loop's epoll watches. No thread is involved (a timer thread, as before,
    must win a core and the GIL before it can wake the loop: under load those wakes came late). Where there is
    no timerfd, it sleeps as ``LoopClock`` does. Not for virtual time: under looptime the loop's time is not
    the kernel's.
    """

    # The estimator's update on a fix took p95 2.2, p99 2.7, max 4.3 ms in a demo flight (both cores busy with the
    # simulator): started closer than this to the setpoint tick, it waits until the tick has run.
    work_margin_s = 0.005

    def __init__(self) -> None:
        super().__init__()
        self._pending: list[tuple[float, int, asyncio.Future[None]]] = []
        self._count = itertools.count()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._fd = -1

    async def sleep(self, dt_s: float) -> None:
        if dt_s <= 0.0:
            await asyncio.sleep(0)
            return
        loop = asyncio.get_running_loop()
        if not self._attach(loop):
            await asyncio.sleep(dt_s)
            return
        fut: asyncio.Future[None] = loop.create_future()
        deadline_s = loop.time() + dt_s
        heapq.heappush(self._pending, (deadline_s, next(self._count), fut))
        if self._pending[0][2] is fut:
            self._arm(deadline_s)
        await fut  # cancelling it is enough: the timer then skips it

    def close(self) -> None:
        if self._fd >= 0:
            if self._loop is not None and not self._loop.is_closed():
                self._loop.remove_reader(self._fd)
            os.close(self._fd)
        self._fd, self._loop, self._pending = -1, None, []

    def _attach(self, loop: asyncio.AbstractEventLoop) -> bool:
        if self._loop is loop:
            return self._fd >= 0
        self.close()
        self._loop = loop
        if _TIMERFD is not None:
            fd = _TIMERFD.create(_CLOCK_MONOTONIC, _TFD_NONBLOCK | _TFD_CLOEXEC)
            if fd >= 0:
                self._fd = fd
                loop.add_reader(fd, self._on_timer)
        return self._fd >= 0

    def _arm(self, deadline_s: float) -> None:
        sec = math.floor(deadline_s)
        nsec = min(999_999_999, math.ceil((deadline_s - sec) * 1e9))  # never before the deadline
        spec = _Itimerspec(_Timespec(0, 0), _Timespec(sec, nsec))
        if _TIMERFD is None or _TIMERFD.settime(self._fd, _TFD_TIMER_ABSTIME, ctypes.byref(spec), None) != 0:
            raise OSError(ctypes.get_errno(), "timerfd_settime failed")

    def _on_timer(self) -> None:
        with contextlib.suppress(BlockingIOError):
            os.read(self._fd, 8)
        assert self._loop is not None
        now_s = self._loop.time()
        while self._pending and (self._pending[0][0] <= now_s or self._pending[0][2].done()):
            fut = heapq.heappop(self._pending)[2]
            if not fut.done():
                fut.set_result(None)
        if self._pending:
            self._arm(self._pending[0][0])


@contextlib.contextmanager
def realtime_thread(priority: int) -> Iterator[str]:
    """Run the calling thread — the event loop's, which wakes the setpoint loop — under SCHED_FIFO at
    ``priority`` (as PX4 runs its tasks on Linux) while the block runs, so another process busy on both cores
    cannot queue it; every thread and process it starts meanwhile (MAVSDK's, the detector's, the simulator)
    starts at normal scheduling (SCHED_RESET_ON_FORK). Needs CAP_SYS_NICE or an RLIMIT_RTPRIO of at least
    ``priority`` (``ulimit -r``); refused, the thread stays as it was. Yields what it got, for the summary."""
    if priority <= 0 or not hasattr(os, "SCHED_RESET_ON_FORK"):
        yield "normal" if priority <= 0 else "normal (no SCHED_FIFO here)"
        return
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO | os.SCHED_RESET_ON_FORK, os.sched_param(priority))
    except OSError as e:
        yield f"normal (SCHED_FIFO {priority} refused: {e.strerror})"
        return
    try:
        yield f"SCHED_FIFO {priority}"
    finally:
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))


# Linux timerfd through libc (os.timerfd_* arrive with Python 3.13)
_CLOCK_MONOTONIC = 1  # the kernel clock behind asyncio loop.time()
_TFD_NONBLOCK = os.O_NONBLOCK
_TFD_CLOEXEC = os.O_CLOEXEC
_TFD_TIMER_ABSTIME = 1


class _Timespec(ctypes.Structure):
    _fields_ = [("tv_sec", ctypes.c_long), ("tv_nsec", ctypes.c_long)]


class _Itimerspec(ctypes.Structure):
    _fields_ = [("it_interval", _Timespec), ("it_value", _Timespec)]


@dataclass(frozen=True)
class _Timerfd:
    create: Callable[..., int]
    settime: Callable[..., int]


def _load_timerfd() -> _Timerfd | None:
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return _Timerfd(libc.timerfd_create, libc.timerfd_settime)
    except (OSError, AttributeError):
        return None


_TIMERFD = _load_timerfd()
