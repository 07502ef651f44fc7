"""Fixtures for the ground-station tests: a real mosquitto per test, a GroundLink running against it, and an
observer client that records what the broker delivers."""

from __future__ import annotations

import asyncio
import json
from collections.abc import AsyncIterator, Callable, Iterator
from contextlib import asynccontextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import aiomqtt
import pytest

from app.gcs.config import GcsSettings
from app.gcs.link import GroundLink
from app.gcs.protocol import Command
from tests.gcs.mosquitto import Broker


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Broker]:
    b = Broker(tmp_path)
    b.start()
    yield b
    b.stop()


def link_settings(broker: Broker, **overrides: Any) -> GcsSettings:
    data: dict[str, Any] = {"broker_url": broker.url, "vehicle_id": "sea1", "reconnect_max_s": 1.0}
    data.update(overrides)
    return GcsSettings.from_mapping(data)


@dataclass
class Handler:
    """The app's command handler in the tests: records every command; rejects with ``reason`` when set."""

    reason: str | None = None
    received: list[Command] = field(default_factory=list)

    def __call__(self, command: Command) -> str | None:
        self.received.append(command)
        return self.reason


@asynccontextmanager
async def running(link: GroundLink, timeout_s: float = 5.0) -> AsyncIterator[GroundLink]:
    """``link.run()`` in a task, connected, for the duration of the block; cancelled after it."""
    task = asyncio.create_task(link.run(), name="gcs.link")
    try:
        async with asyncio.timeout(timeout_s):
            await link.wait_connected()
        yield link
    finally:
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)


async def until(condition: Callable[[], bool], timeout_s: float = 5.0) -> None:
    """Wait until ``condition()`` holds (for state that has no event to wait on, e.g. the link's counters)."""
    async with asyncio.timeout(timeout_s):
        while not condition():  # noqa: ASYNC110 (polling: nothing to await)
            await asyncio.sleep(0.005)


@dataclass
class Observer:
    """A plain MQTT client that records (topic, payload, retain) of everything on its subscriptions."""

    client: aiomqtt.Client
    messages: list[tuple[str, bytes, bool]] = field(default_factory=list)
    _arrived: asyncio.Event = field(default_factory=asyncio.Event)

    def on(self, topic: str) -> list[bytes]:
        return [p for t, p, _ in self.messages if t == topic]

    def json_on(self, topic: str) -> list[Any]:
        return [json.loads(p) for p in self.on(topic)]

    async def wait_for(self, done: Callable[[], bool], timeout_s: float = 5.0) -> None:
        async with asyncio.timeout(timeout_s):
            while not done():
                self._arrived.clear()
                await self._arrived.wait()

    async def publish(self, topic: str, payload: bytes | str, qos: int = 1) -> None:
        await self.client.publish(topic, payload, qos=qos)

    async def _collect(self) -> None:
        async for m in self.client.messages:
            payload = m.payload if isinstance(m.payload, bytes) else str(m.payload).encode()
            self.messages.append((m.topic.value, payload, bool(m.retain)))
            self._arrived.set()


@asynccontextmanager
async def observer(broker: Broker, *topics: str, **client_args: Any) -> AsyncIterator[Observer]:
    client = aiomqtt.Client("127.0.0.1", broker.port, protocol=aiomqtt.ProtocolVersion.V5, **client_args)
    async with client:
        obs = Observer(client)
        for topic in topics:
            await client.subscribe(topic, qos=1)
        task = asyncio.create_task(obs._collect())
        try:
            yield obs
        finally:
            task.cancel()
            await asyncio.gather(task, return_exceptions=True)
