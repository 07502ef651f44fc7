"""The one clock of the app: the asyncio loop's time.

Nothing in ``app/`` reads ``time.time()`` or ``time.monotonic()``; everything asks a ``Clock``. In tests
the loop's time is virtual (looptime), so whole missions run in milliseconds.
"""

from __future__ import annotations

import asyncio
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
