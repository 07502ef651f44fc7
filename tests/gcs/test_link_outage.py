"""GroundLink when the broker or the link itself dies: reconnect time, no lost or doubled QoS-1 command,
state restored, will message."""

from __future__ import annotations

import asyncio
import json
import sys
import threading
import time
from pathlib import Path

import paho.mqtt.client as paho

from app.gcs.link import GroundLink, backoff_s
from app.gcs.protocol import Event, State, Telemetry, Topics
from tests.gcs.conftest import Handler, link_settings, observer, running, until
from tests.gcs.mosquitto import Broker

T = Topics("sea1")
REPO = Path(__file__).resolve().parents[2]


def test_backoff_is_bounded_and_starts_well_under_a_second() -> None:
    """First retry ≤ min (0.2 s), doubling, never above max, jittered down to half."""
    import random

    rng = random.Random(1)
    delays = [[backoff_s(n, 0.2, 2.0, rng) for n in range(12)] for _ in range(200)]
    assert max(d[0] for d in delays) <= 0.2 and min(d[0] for d in delays) >= 0.1
    assert max(max(d) for d in delays) <= 2.0
    assert min(d[11] for d in delays) >= 1.0  # capped at max, jitter in [0.5, 1]


class _Publisher:
    """An operator's client (paho, its own network thread, auto-reconnect): keeps a QoS-1 publish made while
    the broker is down and sends it when the broker is back."""

    def __init__(self, port: int) -> None:
        self.client = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id="operator", clean_session=False)
        self.client.reconnect_delay_set(min_delay=1, max_delay=1)
        self.connected = threading.Event()
        self.client.on_connect = lambda *a: self.connected.set()
        self.client.on_disconnect = lambda *a: self.connected.clear()
        self.client.connect("127.0.0.1", port)
        self.client.loop_start()

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


async def test_broker_killed_and_restarted_reconnects_within_5_s_and_loses_no_command(tmp_path: Path) -> None:
    """SIGKILL the broker; one command is published during the outage, one right after the broker is back
    (before the link is): the link is back within 5 s and the handler gets each command exactly once."""
    broker = Broker(tmp_path, persistence=True)  # the link's session must survive the broker's restart
    broker.start()
    handler = Handler()
    link = GroundLink(link_settings(broker, reconnect_max_s=2.0), handler)
    publisher = _Publisher(broker.port)
    try:
        async with running(link):
            assert await asyncio.to_thread(publisher.connected.wait, 5.0)
            broker.kill()
            await until(lambda: not link.connected)
            publisher.client.publish(T.cmd, b'{"cmd":"abort","id":"during"}', qos=1)  # queued by the client
            await asyncio.sleep(1.5)
            broker.start()
            back = time.monotonic()
            async with observer(broker) as late:
                link_was_up = link.connected
                await late.publish(T.cmd, b'{"cmd":"hold","id":"after"}')
            await until(lambda: link.counters.reconnects >= 1)
            reconnect_s = time.monotonic() - back
            print(
                f"\nGroundLink reconnected {reconnect_s:.2f} s after the broker came back "
                f"(link already back when 'after' was published: {link_was_up})"
            )
            await until(lambda: len(handler.received) >= 2)
            await asyncio.sleep(1.5)  # a redelivered duplicate would show by now (the publisher retries at 1 s)
    finally:
        publisher.close()
        broker.stop()
    assert reconnect_s < 5.0
    assert sorted(c.id for c in handler.received) == ["after", "during"]


async def test_after_a_restart_that_lost_everything_the_link_restores_online_and_state(tmp_path: Path) -> None:
    """A broker without persistence forgets retained messages: the link re-announces online and re-sends the
    latest state; events published while it was down follow; telemetry offered meanwhile is dropped."""
    broker = Broker(tmp_path)
    broker.start()
    link = GroundLink(link_settings(broker), Handler())
    try:
        async with running(link):
            link.publish_state(State(mission_state="SEARCH", flight_mode="OFFBOARD", armed=True))
            await asyncio.sleep(0.2)
            broker.kill()
            await until(lambda: not link.connected)
            link.publish_event(Event(t_s=1.0, kind="target_lost"))
            link.publish_telemetry(Telemetry(t_s=1.0, position_ned_m=(0.0, 0.0, -5.0)))
            broker.start()
            async with asyncio.timeout(5):
                await link.wait_connected()
            async with observer(broker, T.online, T.state) as late:
                await late.wait_for(lambda: bool(late.on(T.online)) and bool(late.on(T.state)))
            assert late.on(T.online) == [b"true"]
            assert json.loads(late.on(T.state)[0])["mission_state"] == "SEARCH"
            assert link.counters.telemetry_dropped == 1
            await until(lambda: link.counters.events_sent >= 1)
    finally:
        broker.stop()


async def test_the_will_marks_the_vehicle_offline_when_the_link_process_is_killed(broker: Broker) -> None:
    """kill -9 of the process running the link: the broker publishes online=false, retained."""
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "tests.gcs.link_process", broker.url, "sea1", cwd=REPO, stdout=asyncio.subprocess.PIPE
    )
    try:
        async with asyncio.timeout(10):
            assert await proc.stdout.readline() == b"connected\n"  # type: ignore[union-attr]
        async with observer(broker, T.online) as obs:
            await obs.wait_for(lambda: obs.on(T.online) == [b"true"])
            proc.kill()
            await obs.wait_for(lambda: obs.on(T.online) == [b"true", b"false"])
    finally:
        if proc.returncode is None:
            proc.kill()
        await proc.wait()
    async with observer(broker, T.online) as late:
        await late.wait_for(lambda: bool(late.messages))
    assert late.messages == [(T.online, b"false", True)]


async def test_a_clean_shutdown_also_marks_the_vehicle_offline(broker: Broker) -> None:
    """Cancelling run() publishes online=false, retained, before disconnecting (no will on a clean exit)."""
    async with running(GroundLink(link_settings(broker), Handler())):
        pass
    async with observer(broker, T.online) as late:
        await late.wait_for(lambda: bool(late.messages))
    assert late.messages == [(T.online, b"false", True)]
