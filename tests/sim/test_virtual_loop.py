"""The evaluation's virtual-time event loop: looptime's clock, tick for tick, and a run that is the same on either."""

from __future__ import annotations

import asyncio
import json
import socket
import threading
from collections.abc import Coroutine
from typing import Any, TypeVar

import looptime
import pytest

from sim.evaluate_pickup import run_pickup
from sim.pickup_scenarios import sample_scenario
from sim.virtual_loop import VirtualTimeLoop

T = TypeVar("T")


async def _timeline() -> list[float]:
    """Loop times seen by three tasks sleeping at awkward periods, a timeout and a sub-tick sleep."""
    loop = asyncio.get_running_loop()
    seen: list[float] = []

    async def every(period_s: float, n: int) -> None:
        for _ in range(n):
            await asyncio.sleep(period_s)
            seen.append(loop.time())

    async with asyncio.TaskGroup() as tg:
        tg.create_task(every(0.02, 500))
        tg.create_task(every(1 / 15, 150))
        tg.create_task(every(0.005, 2000))
    try:
        async with asyncio.timeout(0.37):
            await asyncio.sleep(10.0)
    except TimeoutError:
        seen.append(loop.time())
    await asyncio.sleep(1e-7)  # shorter than a tick: the clock still moves
    seen.append(loop.time())
    return seen


def _run(loop: asyncio.AbstractEventLoop, coro: Coroutine[Any, Any, T]) -> T:
    try:
        return loop.run_until_complete(coro)
    finally:
        loop.close()


def test_the_clock_reads_what_looptimes_reads_at_every_wake():
    virtual = _run(VirtualTimeLoop(), _timeline())
    reference = _run(looptime.new_event_loop(noop_cycles=0), _timeline())
    assert len(virtual) == 2652
    assert virtual == reference  # exactly: the same integer clock
    assert virtual[-2] == pytest.approx(10.0 + 0.37, abs=1e-3) and virtual[-1] > virtual[-2]


def test_it_starts_at_zero_and_runs_ten_virtual_minutes_at_once():
    loop = VirtualTimeLoop()
    assert loop.time() == 0.0
    _run(loop, asyncio.sleep(600.0))
    assert loop.time() == 600.0


def test_waiting_with_nothing_scheduled_is_an_error_not_a_hang():
    loop = VirtualTimeLoop()

    async def wait_forever() -> None:
        await loop.create_future()

    with pytest.raises(RuntimeError, match="nothing is scheduled"):
        _run(loop, wait_forever())


def test_io_is_refused():
    loop = VirtualTimeLoop()
    a, b = socket.socketpair()
    try:
        with pytest.raises(RuntimeError, match="does no I/O"):
            loop.add_reader(a.fileno(), lambda: None)
    finally:
        a.close()
        b.close()
        loop.close()


def test_a_callback_from_another_thread_runs_at_a_later_iteration():
    loop = VirtualTimeLoop()
    got: list[float] = []

    async def main() -> None:
        threading.Thread(target=lambda: loop.call_soon_threadsafe(lambda: got.append(loop.time()))).start()
        # polling on purpose: nothing but a timer makes virtual time wait for the thread
        while not got:  # noqa: ASYNC110
            await asyncio.sleep(0.01)

    _run(loop, main())
    assert len(got) == 1 and got[0] >= 0.0


def test_a_pickup_run_is_the_same_on_looptime(monkeypatch):
    """One whole evaluation run (PX4, buoy, sea state 3: 81 s of mission; 145 s before the transit legs flew at
    5 m/s), on this loop and on looptime."""
    scenario = sample_scenario(1, 1, 3)
    virtual = run_pickup(scenario, "seapick", 1)
    monkeypatch.setattr("sim.evaluate_pickup.VirtualTimeLoop", lambda: looptime.new_event_loop(noop_cycles=0))
    reference = run_pickup(scenario, "seapick", 1)
    for r in (virtual, reference):
        r.pop("wall_s")
    assert virtual["outcome"] == "picked_up" and virtual["mission_s"] > 60.0  # a whole mission, home and landed
    assert json.dumps(virtual, sort_keys=True) == json.dumps(reference, sort_keys=True)
