"""An asyncio event loop in virtual time for runs that do no I/O and start no threads: the evaluation's.

When nothing is ready to run, the loop's clock jumps to the next timer — what ``looptime`` does with
``noop_cycles=0``, and on the same integer clock (microseconds, the time read back as ``ticks / 1_000_000``), so
a run gives the same result, bit for bit, on either loop. It is faster because a jump costs one loop iteration
and no system call: ``looptime`` first polls the real selector (``epoll_wait``) on every iteration and spends an
iteration without moving the clock before each jump. That is a fifth of an evaluation run's CPU time.

What it cannot do, it refuses: a reader or writer on a file descriptor (I/O) raises ``RuntimeError``, and so does
waiting with nothing scheduled (a run that would never end). Callbacks another thread hands over with
``call_soon_threadsafe`` still run, at the loop's next iteration, but nothing waits for them: a run that needs
a thread belongs on ``looptime`` (tests) or on the real clock.
"""

from __future__ import annotations

import asyncio
import selectors
from typing import Any

TICKS_PER_S = 1_000_000  # looptime's default resolution, 1 µs


class _VirtualSelector(selectors.BaseSelector):
    """A selector with nothing to select: waiting ``timeout`` seconds moves the loop's clock by as much."""

    def __init__(self) -> None:
        self._map: dict[Any, selectors.SelectorKey] = {}
        self.loop: VirtualTimeLoop | None = None

    def register(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        if self.loop is not None and self.loop.setup_done:  # only the loop's own self-pipe, while it is built
            raise RuntimeError("a virtual-time run does no I/O: nothing may wait on a file descriptor")
        fd = fileobj if isinstance(fileobj, int) else fileobj.fileno()
        key = selectors.SelectorKey(fileobj, fd, events, data)
        self._map[fileobj] = key
        return key

    def unregister(self, fileobj: Any) -> selectors.SelectorKey:
        return self._map.pop(fileobj)

    def get_map(self) -> Any:
        return self._map

    def select(self, timeout: float | None = None) -> list[tuple[selectors.SelectorKey, int]]:
        loop = self.loop
        assert loop is not None
        if timeout is None:
            raise RuntimeError("nothing is scheduled: a virtual-time run would wait forever")
        if timeout > 0.0:
            # looptime's step: rounded to whole ticks, at least one for a timeout shorter than a tick
            step = round(timeout * TICKS_PER_S)
            if timeout < 1.0 / TICKS_PER_S:
                step += 1
            loop.ticks += step
        return []

    def close(self) -> None:
        self._map.clear()


class VirtualTimeLoop(asyncio.SelectorEventLoop):
    """``asyncio.SelectorEventLoop`` whose clock is virtual: see the module docstring. Starts at 0 s."""

    def __init__(self) -> None:
        selector = _VirtualSelector()
        self.ticks = 0
        self.setup_done = False
        selector.loop = self
        super().__init__(selector)
        self.setup_done = True

    def time(self) -> float:
        return self.ticks / TICKS_PER_S

    def _write_to_self(self) -> None:
        pass  # the loop never blocks in real time: there is nothing to wake
