"""The latest-wins queue: the oldest item goes when full and is counted, and nothing else is ever lost."""

from __future__ import annotations

import asyncio
import threading
import time

import pytest

from app.queues import LatestQueue, QueueShutDown

WAIT_S = 5.0


def test_a_full_queue_drops_the_oldest_and_counts_it() -> None:
    q: LatestQueue[int] = LatestQueue(maxsize=3)
    for i in range(5):
        q.put(i)
    assert (q.qsize(), q.put_count, q.dropped) == (3, 5, 2)
    assert [q.take(), q.take(), q.take(), q.take()] == [2, 3, 4, None]


def test_with_one_slot_take_hands_over_only_the_newest() -> None:
    q: LatestQueue[int] = LatestQueue(maxsize=1)
    assert q.take() is None
    for i in range(3):
        q.put(i)
    assert q.take() == 2
    assert q.take() is None
    assert (q.put_count, q.dropped) == (3, 2)


def test_clear_counts_what_it_throws_away() -> None:
    q: LatestQueue[int] = LatestQueue(maxsize=4)
    for i in range(3):
        q.put(i)
    q.clear()
    assert (q.qsize(), q.take(), q.dropped) == (0, None, 3)


@pytest.mark.parametrize("maxsize", [0, -1])
def test_a_queue_holds_at_least_one_item(maxsize: int) -> None:
    with pytest.raises(ValueError, match="at least one"):
        LatestQueue[int](maxsize)


async def test_get_and_take_hand_items_over_oldest_first() -> None:
    q: LatestQueue[str] = LatestQueue(maxsize=4)
    for item in "abc":
        q.put(item)
    assert await q.get() == "a"
    assert q.take() == "b"
    assert await q.get() == "c"


async def test_get_waits_for_a_put_on_the_loop() -> None:
    q: LatestQueue[int] = LatestQueue(maxsize=2)
    getter = asyncio.create_task(q.get())
    await asyncio.sleep(0)
    assert not getter.done()
    q.put(7)
    assert await asyncio.wait_for(getter, WAIT_S) == 7


async def test_get_wakes_when_another_thread_puts() -> None:
    q: LatestQueue[int] = LatestQueue(maxsize=1)
    getter = asyncio.create_task(q.get())
    await asyncio.sleep(0.01)  # the getter is parked on its future
    assert not getter.done()
    producer = threading.Thread(target=q.put, args=(42,))
    producer.start()
    assert await asyncio.wait_for(getter, WAIT_S) == 42
    producer.join()


async def test_a_cancelled_get_leaves_the_item_for_the_next_one() -> None:
    q: LatestQueue[int] = LatestQueue(maxsize=1)
    getter = asyncio.create_task(q.get())
    await asyncio.sleep(0)
    getter.cancel()
    with pytest.raises(asyncio.CancelledError):
        await getter
    q.put(1)
    assert await asyncio.wait_for(q.get(), WAIT_S) == 1


async def test_shutdown_wakes_a_waiting_get_once_the_queue_is_empty() -> None:
    q: LatestQueue[int] = LatestQueue(maxsize=2)
    getter = asyncio.create_task(q.get())
    await asyncio.sleep(0.01)
    threading.Thread(target=q.shutdown).start()  # e.g. the producer thread failing
    with pytest.raises(QueueShutDown):
        await asyncio.wait_for(getter, WAIT_S)
    with pytest.raises(QueueShutDown):
        q.put(1)


async def test_items_left_at_shutdown_are_still_handed_over() -> None:
    q: LatestQueue[int] = LatestQueue(maxsize=2)
    q.put(1)
    q.shutdown()
    assert await q.get() == 1
    with pytest.raises(QueueShutDown):
        await q.get()


@pytest.mark.parametrize("maxsize", [1, 8])
async def test_a_producer_thread_loses_nothing_but_the_counted_drops(maxsize: int) -> None:
    q: LatestQueue[int] = LatestQueue(maxsize)
    n = 20_000

    def produce() -> None:
        for i in range(n):
            q.put(i)
            if i % 500 == 0:
                time.sleep(0.0005)  # let the consumer catch up now and then, so both paths run

    received: list[int] = []
    producer = threading.Thread(target=produce)
    producer.start()
    try:
        while producer.is_alive() or q.qsize():
            try:
                received.append(await asyncio.wait_for(q.get(), 0.05))
            except TimeoutError:  # the producer finished while we waited
                pass
    finally:
        producer.join()
    assert q.put_count == n
    assert q.put_count == len(received) + q.dropped + q.qsize()
    assert received == sorted(set(received))  # each item once, in the order it was put
    assert received[-1] == n - 1  # the newest is never the one dropped
