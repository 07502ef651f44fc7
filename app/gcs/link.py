"""``GroundLink``: the vehicle's end of the ground-station protocol (``app/gcs/protocol.py``) over aiomqtt.

``run()`` keeps one connection to the broker for as long as it runs: it announces ``online`` (retained;
the will message sets it ``false`` when the connection dies, and a clean shutdown does the same), subscribes
to ``cmd`` at QoS 1 and answers every message there on ``cmd/ack``:

- a payload that is not a valid command → a rejected ack naming the problem (``id`` null when it had no
  readable one); nothing else happens;
- an id seen among the last ``dedupe_window`` commands → the ack it got the first time, again; the
  handler is not called again (QoS 1 is at-least-once: the broker may deliver a command twice);
- otherwise the app's handler decides (``None``: accepted; a string: rejected, with that reason).

Reconnects wait a bounded exponential backoff with jitter (``reconnect_min_s`` … ``reconnect_max_s``). The
session is persistent across reconnects (fixed client id, MQTT v5 ``clean_start=False`` with a session
expiry ``session_expiry_s``), so a QoS-1 command published while the link was down is delivered when it is
back — provided the broker still has the session (a broker restart loses it unless the broker persists
sessions: mosquitto ``persistence true``). Before its first session a process connects once with a clean
start and leaves: commands queued for an earlier run are dropped, not executed.

Outgoing: ``publish_state`` (retained, QoS 1; the latest is re-sent on every reconnect),
``publish_telemetry`` (latest wins, at most ``telemetry_rate_hz``; dropped and counted while disconnected),
``publish_event`` (QoS 1, a bounded queue that keeps the newest ``event_queue_size`` while disconnected,
counting what it drops). All three are plain calls from the event loop's thread; they never block.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import random
from collections import OrderedDict
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import aiomqtt

from app.clock import Clock, LoopClock
from app.gcs.config import GcsSettings
from app.gcs.protocol import (
    OFFLINE,
    ONLINE,
    Ack,
    Command,
    Event,
    MalformedCommand,
    State,
    Telemetry,
    encode,
    parse_command,
)
from app.gcs.transport import mqtt_client
from app.queues import LatestQueue

log = logging.getLogger(__name__)

CommandHandler = Callable[[Command], str | None]
"""Decides a command on the event loop: ``None`` accepts it, a string rejects it with that reason."""


@dataclass(frozen=True)
class LinkCounters:
    connects: int = 0  # successful connections, the first included
    reconnects: int = 0  # successful connections after the first
    commands: int = 0  # handed to the handler
    accepted: int = 0
    rejected: int = 0  # by the handler (its reason in the ack)
    handler_errors: int = 0  # the handler raised: rejected as "internal error"
    malformed: int = 0
    duplicates: int = 0
    telemetry_sent: int = 0
    telemetry_dropped: int = 0  # replaced by a newer one before it went out, or offered while disconnected
    events_sent: int = 0
    events_dropped: int = 0  # pushed out of the full queue, or lost with the connection


def backoff_s(failures: int, min_s: float, max_s: float, rng: random.Random) -> float:
    """Delay before reconnect attempt ``failures + 1``: min·2^failures capped at max, times a jitter in [0.5, 1]."""
    ceiling = min(max_s, min_s * 2.0 ** min(failures, 30))
    return ceiling * rng.uniform(0.5, 1.0)


class GroundLink:
    def __init__(
        self,
        settings: GcsSettings,
        handler: CommandHandler,
        *,
        clock: Clock | None = None,
        rng: random.Random | None = None,
        environ: Mapping[str, str] | None = None,
    ) -> None:
        """Reads the password (``settings.password_env``) and the TLS files now: a ``ConfigError`` here, not later."""
        self.settings = settings
        self.topics = settings.topics
        self._handler = handler
        self._clock = clock or LoopClock()
        self._rng = rng or random.Random()
        self._password = settings.password(environ)
        self._tls = settings.tls_context()
        self._counts: dict[str, int] = dict.fromkeys(LinkCounters.__dataclass_fields__, 0)
        self._acks: OrderedDict[str, Ack] = OrderedDict()
        self._state: State | None = None
        self._state_sent: State | None = None
        self._state_changed = asyncio.Event()
        self._telemetry: LatestQueue[Telemetry] = LatestQueue(1)
        self._events: LatestQueue[Event] = LatestQueue(settings.event_queue_size)
        self._connected = asyncio.Event()
        self._failures = 0
        self._session_wiped = False
        self._sending = False  # an event is being published

    # ---- what the app calls ---------------------------------------------------------------------------

    @property
    def connected(self) -> bool:
        return self._connected.is_set()

    async def wait_connected(self) -> None:
        """Return once the link is connected, subscribed and has announced itself."""
        await self._connected.wait()

    @property
    def counters(self) -> LinkCounters:
        counts = dict(self._counts)
        counts["telemetry_dropped"] += self._telemetry.dropped
        counts["events_dropped"] += self._events.dropped
        return LinkCounters(**counts)

    def publish_state(self, state: State) -> None:
        """The vehicle's state, retained; sent when it differs from the last one sent, and on every reconnect."""
        self._state = state
        if state != self._state_sent:
            self._state_changed.set()

    def publish_telemetry(self, telemetry: Telemetry) -> None:
        """Latest wins: sent at the next telemetry tick unless a newer one replaces it; dropped while disconnected."""
        if not self.connected:
            self._counts["telemetry_dropped"] += 1
            return
        self._telemetry.put(telemetry)

    def publish_event(self, event: Event) -> None:
        """Queued (bounded: the oldest is dropped when full) and sent in order, also after a reconnect."""
        self._events.put(event)

    async def flush(self, timeout_s: float) -> bool:
        """Wait until the latest state and every queued event have gone out (at most ``timeout_s``); True if so."""
        deadline_s = self._clock.now_s() + timeout_s
        while True:
            if self.connected and self._state_sent == self._state and not self._events.qsize() and not self._sending:
                return True
            if self._clock.now_s() >= deadline_s:
                return False
            await self._clock.sleep(0.02)

    # ---- commands: pure, no I/O -----------------------------------------------------------------------

    def answer(self, payload: bytes) -> Ack:
        """The ack for one message on ``cmd``; calls the handler only for a valid command with a new id."""
        try:
            command = parse_command(payload)
        except MalformedCommand as e:
            self._counts["malformed"] += 1
            log.warning("gcs: malformed command (id %s): %s", e.cmd_id, e.reason[:200])
            return Ack(id=e.cmd_id, cmd=e.cmd, accepted=False, reason=e.reason)
        first = self._acks.get(command.id)
        if first is not None:
            self._counts["duplicates"] += 1
            log.info("gcs: duplicate command id %s (%s): answered as before, not run again", command.id, command.cmd)
            return first
        self._counts["commands"] += 1
        try:
            reason = self._handler(command)
        except Exception as e:  # a bug in the app's handler: say so, keep the link up
            log.exception("gcs: the command handler failed on %s id %s", command.cmd, command.id)
            self._counts["handler_errors"] += 1
            reason = f"internal error: {type(e).__name__}"
        self._counts["accepted" if reason is None else "rejected"] += 1
        ack = Ack(id=command.id, cmd=command.cmd, accepted=reason is None, reason=reason)
        log.info("gcs: %s id %s %s", command.cmd, command.id, "accepted" if reason is None else f"rejected: {reason}")
        self._acks[command.id] = ack
        while len(self._acks) > self.settings.dedupe_window:
            self._acks.popitem(last=False)
        return ack

    # ---- the connection -------------------------------------------------------------------------------

    async def run(self) -> None:
        """Stay connected until cancelled (reconnecting with backoff); on cancellation announce ``online`` false."""
        s = self.settings
        last_problem = ""
        while True:
            try:
                await self._session()
            except* aiomqtt.MqttError as group:
                problem = "; ".join(str(e) or type(e).__name__ for e in group.exceptions)
                delay_s = backoff_s(self._failures, s.reconnect_min_s, s.reconnect_max_s, self._rng)
                level = logging.WARNING if problem != last_problem or self._failures == 0 else logging.DEBUG
                log.log(level, "gcs: no broker at %s (%s); retrying in %.2f s", s.broker_url, problem, delay_s)
                last_problem = problem
            else:
                delay_s = backoff_s(self._failures, s.reconnect_min_s, s.reconnect_max_s, self._rng)
            self._failures += 1
            await self._clock.sleep(delay_s)

    async def _session(self) -> None:
        """One connection, from connect to its loss (raises ``MqttError``, or ``CancelledError``)."""
        s, t = self.settings, self.topics
        if not self._session_wiped:
            # Drop whatever a previous run left queued (a stale start must not fly the vehicle): connect with a
            # clean start and no expiry, then leave. The session proper then always connects with clean_start
            # False — mosquitto (2.0.11) persists across its own restarts only sessions made that way.
            async with self._client(clean_start=True, session_expiry_s=0, will=None):
                pass
            self._session_wiped = True
        will = aiomqtt.Will(t.online, OFFLINE, qos=1, retain=True)
        async with self._client(clean_start=False, session_expiry_s=s.session_expiry_s, will=will) as client:
            self._counts["connects"] += 1
            if self._counts["connects"] > 1:
                self._counts["reconnects"] += 1
            self._failures = 0
            try:
                await client.subscribe(t.cmd, qos=1)
                await client.publish(t.online, ONLINE, qos=1, retain=True)
                self._state_sent = None  # re-send the latest state on every connection
                if self._state is not None:
                    self._state_changed.set()
                log.info("gcs: connected to %s as %s", s.broker_url, s.client_id)
                self._connected.set()
                async with asyncio.TaskGroup() as tg:
                    tg.create_task(self._receive(client), name="gcs.receive")
                    tg.create_task(self._send_state(client), name="gcs.state")
                    tg.create_task(self._send_telemetry(client), name="gcs.telemetry")
                    tg.create_task(self._send_events(client), name="gcs.events")
            except asyncio.CancelledError:
                self._connected.clear()
                with contextlib.suppress(aiomqtt.MqttError, TimeoutError):
                    await client.publish(t.online, OFFLINE, qos=1, retain=True, timeout=1.0)
                raise
            finally:
                self._connected.clear()
                self._telemetry.clear()  # stale by the time we are back: counted as dropped

    def _client(self, *, clean_start: bool, session_expiry_s: int, will: aiomqtt.Will | None) -> aiomqtt.Client:
        return mqtt_client(
            self.settings,
            identifier=self.settings.client_id,
            password=self._password,
            tls_context=self._tls,
            clean_start=clean_start,
            session_expiry_s=session_expiry_s,
            will=will,
        )

    async def _receive(self, client: aiomqtt.Client) -> None:
        async for message in client.messages:
            if not message.topic.matches(self.topics.cmd):
                continue
            payload = message.payload
            data = payload if isinstance(payload, bytes) else str(payload or "").encode()
            ack = self.answer(bytes(data))
            await client.publish(self.topics.ack, encode(ack), qos=1)

    async def _send_state(self, client: aiomqtt.Client) -> None:
        while True:
            await self._state_changed.wait()
            self._state_changed.clear()
            state = self._state
            if state is not None and state != self._state_sent:
                await client.publish(self.topics.state, encode(state), qos=1, retain=True)
                self._state_sent = state

    async def _send_telemetry(self, client: aiomqtt.Client) -> None:
        period_s = 1.0 / self.settings.telemetry_rate_hz
        while True:
            await self._clock.sleep(period_s)
            telemetry = self._telemetry.take()
            if telemetry is not None:
                await client.publish(self.topics.telemetry, encode(telemetry), qos=0)
                self._counts["telemetry_sent"] += 1

    async def _send_events(self, client: aiomqtt.Client) -> None:
        while True:
            event = await self._events.get()
            self._sending = True
            try:
                await client.publish(self.topics.events, encode(event), qos=1)
            except aiomqtt.MqttError:
                self._counts["events_dropped"] += 1
                raise
            finally:
                self._sending = False
            self._counts["events_sent"] += 1
