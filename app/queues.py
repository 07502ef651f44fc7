"""The one queue between a producer and the event loop: bounded, latest-wins, and it counts what it drops.

A sensor produces at its own rate whether or not the consumer keeps up; a queue that grew (or blocked the
producer) would hand the estimators stale data. So a put on a full queue drops the *oldest* item and counts
it (``dropped``), and the consumer gets the oldest item still queued — with ``maxsize`` 1 that is the newest.

Producers may be the loop itself (the radar's message callback) or a blocking thread (the camera's capture
thread), so the items sit behind a ``threading.Lock``. The asyncio side is touched only on its own loop: a put
wakes a waiting ``get`` through ``loop.call_soon_threadsafe``, from whichever thread it runs in.
"""

from __future__ import annotations

import asyncio
import threading
from collections import deque
from typing import Generic, TypeVar

T = TypeVar("T")


class QueueShutDown(Exception):
    """Raised by ``get`` on a queue that was shut down and has nothing left (and by ``put`` after the shutdown)."""


class LatestQueue(Generic[T]):
    """Bounded, latest-wins, thread-safe: ``put`` from any thread, ``take`` anywhere, ``get`` on a loop.

    ``put_count`` counts every item put, ``dropped`` those pushed out unseen, so that at any time
    ``put_count == taken + dropped + qsize()``.
    """

    def __init__(self, maxsize: int) -> None:
        if maxsize < 1:
            raise ValueError(f"a latest-wins queue holds at least one item, got maxsize {maxsize}")
        self.maxsize = maxsize
        self.put_count = 0
        self.dropped = 0
        self._lock = threading.Lock()
        self._items: deque[T] = deque()
        self._waiters: list[asyncio.Future[None]] = []  # one per pending get(), each on its own loop
        self._shut_down = False

    def put(self, item: T) -> None:
        """Queue ``item``, dropping (and counting) the oldest one when full; never blocks."""
        with self._lock:
            if self._shut_down:
                raise QueueShutDown("put on a queue that was shut down")
            if len(self._items) >= self.maxsize:
                self._items.popleft()
                self.dropped += 1
            self._items.append(item)
            self.put_count += 1
            waiters, self._waiters = self._waiters, []
        _wake(waiters)

    def take(self) -> T | None:
        """The oldest item still queued, removed (``None`` when the queue is empty); never blocks."""
        with self._lock:
            return self._items.popleft() if self._items else None

    async def get(self) -> T:
        """The oldest item still queued, removed; waits on the running loop until there is one.

        Raises ``QueueShutDown`` once the queue was shut down and every item left has been taken.
        """
        loop = asyncio.get_running_loop()
        while True:
            with self._lock:  # check and register together: a put between them would wake nobody
                if self._items:
                    return self._items.popleft()
                if self._shut_down:
                    raise QueueShutDown("the queue was shut down")
                waiter: asyncio.Future[None] = loop.create_future()
                self._waiters.append(waiter)
            try:
                await waiter
            finally:
                with self._lock:
                    if waiter in self._waiters:  # cancelled before a put took it off the list
                        self._waiters.remove(waiter)

    def qsize(self) -> int:
        with self._lock:
            return len(self._items)

    def clear(self) -> None:
        """Drop every queued item, counted in ``dropped`` (nothing leaves the queue uncounted)."""
        with self._lock:
            self.dropped += len(self._items)
            self._items.clear()

    def shutdown(self) -> None:
        """No more items will come (the producer failed or ended): a waiting ``get`` raises ``QueueShutDown``
        once the items still queued are taken, and so does any later ``put``."""
        with self._lock:
            self._shut_down = True
            waiters, self._waiters = self._waiters, []
        _wake(waiters)


def _wake(waiters: list[asyncio.Future[None]]) -> None:
    """Resolve each waiter on its own loop (the caller may be any thread); a closed loop has nobody waiting."""
    for waiter in waiters:
        try:
            waiter.get_loop().call_soon_threadsafe(_resolve, waiter)
        except RuntimeError:  # the loop is closed
            pass


def _resolve(waiter: asyncio.Future[None]) -> None:
    if not waiter.done():  # a cancelled get() has already given up
        waiter.set_result(None)
