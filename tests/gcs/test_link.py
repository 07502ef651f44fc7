"""GroundLink against a real mosquitto: commands, acks, duplicates, malformed floods, state/telemetry/events."""

from __future__ import annotations

import asyncio
import json
import random

from app.gcs.link import GroundLink
from app.gcs.protocol import Event, Start, State, Telemetry, Topics, encode
from tests.gcs.conftest import Handler, link_settings, observer, running
from tests.gcs.mosquitto import Broker

T = Topics("sea1")


async def test_an_accepted_command_reaches_the_handler_and_is_acked(broker: Broker) -> None:
    """A valid start is handed to the handler with its fields, and acked accepted with its id and name."""
    handler = Handler()
    async with running(GroundLink(link_settings(broker), handler)), observer(broker, T.ack) as obs:
        await obs.publish(T.cmd, b'{"cmd":"start","id":"c1","start_ne_m":[10,-5.5],"search_radius_m":30}')
        await obs.wait_for(lambda: len(obs.on(T.ack)) == 1)
    assert handler.received == [Start(id="c1", start_ne_m=(10.0, -5.5), search_radius_m=30.0)]
    assert obs.json_on(T.ack) == [{"id": "c1", "cmd": "start", "accepted": True, "reason": None}]


async def test_a_rejected_command_is_acked_with_the_handlers_reason(broker: Broker) -> None:
    """The handler's reason travels in the ack, accepted false."""
    handler = Handler(reason="not valid in SEARCH: pilot has control")
    async with running(GroundLink(link_settings(broker), handler)), observer(broker, T.ack) as obs:
        await obs.publish(T.cmd, b'{"cmd":"authorize_land","id":"x9"}')
        await obs.wait_for(lambda: len(obs.on(T.ack)) == 1)
    assert obs.json_on(T.ack) == [
        {"id": "x9", "cmd": "authorize_land", "accepted": False, "reason": "not valid in SEARCH: pilot has control"}
    ]


async def test_a_duplicate_id_runs_once_and_gets_the_first_ack_again(broker: Broker) -> None:
    """Same id three times (even with another command): the handler sees it once; every ack is the first one."""
    handler = Handler()
    link = GroundLink(link_settings(broker), handler)
    async with running(link), observer(broker, T.ack) as obs:
        await obs.publish(T.cmd, b'{"cmd":"hold","id":"d1"}')
        await obs.publish(T.cmd, b'{"cmd":"hold","id":"d1"}')
        await obs.publish(T.cmd, b'{"cmd":"abort","id":"d1"}')
        await obs.wait_for(lambda: len(obs.on(T.ack)) == 3)
    assert [c.id for c in handler.received] == ["d1"] and handler.received[0].cmd == "hold"
    assert obs.json_on(T.ack) == [{"id": "d1", "cmd": "hold", "accepted": True, "reason": None}] * 3
    assert link.counters.duplicates == 2 and link.counters.commands == 1


def _malformed(rng: random.Random) -> bytes:
    """One of many kinds of bad payload."""
    kind = rng.randrange(12)
    n = rng.randrange(1_000_000)
    return [
        lambda: b"{not json" + str(n).encode(),
        lambda: b'{"cmd":"start","id":' + str(n).encode() + b"}",  # id of the wrong type
        lambda: f'{{"cmd":"fly_{n}","id":"m{n}"}}'.encode(),  # unknown command
        lambda: f'{{"cmd":"start","id":"m{n}","start_ne_m":["a",{n}]}}'.encode(),
        lambda: f'{{"cmd":"start","id":"m{n}","search_radius_m":"{n}"}}'.encode(),  # "1" is not a number
        lambda: f'{{"cmd":"abort","id":"m{n}","extra":{n}}}'.encode(),
        lambda: b'{"cmd":"abort","id":"' + b"x" * 5000 + b'"}',  # huge
        lambda: bytes(rng.randrange(256) for _ in range(rng.randrange(1, 64))) + b"\xff",  # binary, not UTF-8
        lambda: f'[{{"cmd":"abort","id":"m{n}"}}]'.encode(),  # not an object
        lambda: f'{{"cmd":"start","id":"m{n}","search_radius_m":NaN}}'.encode(),
        lambda: b"",
        lambda: f'{{"cmd":"hold","id":"m{n}","id":"again"}}'.encode(),  # duplicate key
    ][kind]()


async def test_1000_malformed_payloads_are_each_answered_with_an_error_and_nothing_runs(broker: Broker) -> None:
    """1000 bad payloads of 12 kinds: 1000 rejected acks with a reason, the handler never called; then a
    valid command still works."""
    handler = Handler()
    link = GroundLink(link_settings(broker), handler)
    rng = random.Random(12)
    payloads = [_malformed(rng) for _ in range(1000)]
    async with running(link), observer(broker, T.ack) as obs:
        await asyncio.gather(*(obs.publish(T.cmd, p) for p in payloads))
        await obs.wait_for(lambda: len(obs.on(T.ack)) == 1000, timeout_s=20.0)
        assert handler.received == []
        acks = obs.json_on(T.ack)
        assert all(a["accepted"] is False and a["reason"] for a in acks)
        assert link.counters.malformed == 1000
        reasons = " | ".join(a["reason"] for a in acks)
        for problem in ("not valid JSON", "unknown command", "not UTF-8", "at most 4096", "unknown field"):
            assert problem in reasons
        await obs.publish(T.cmd, b'{"cmd":"rtl","id":"after"}')
        await obs.wait_for(lambda: len(obs.on(T.ack)) == 1001)
    assert [c.id for c in handler.received] == ["after"]
    assert obs.json_on(T.ack)[-1] == {"id": "after", "cmd": "rtl", "accepted": True, "reason": None}


async def test_a_malformed_command_with_a_readable_id_is_answered_under_that_id(broker: Broker) -> None:
    """The error ack names the id and command when they could be read, and the field that is wrong."""
    async with running(GroundLink(link_settings(broker), Handler())), observer(broker, T.ack) as obs:
        await obs.publish(T.cmd, b'{"cmd":"start","id":"s7","search_radius_m":-3}')
        await obs.wait_for(lambda: len(obs.on(T.ack)) == 1)
    [ack] = obs.json_on(T.ack)
    assert (ack["id"], ack["cmd"], ack["accepted"]) == ("s7", "start", False)
    assert ack["reason"].startswith("search_radius_m: Input should be greater than 0")


async def test_online_and_the_latest_state_are_retained_for_late_subscribers(broker: Broker) -> None:
    """A client subscribing after the fact gets online true and the last state published, retained."""
    link = GroundLink(link_settings(broker), Handler())
    async with running(link):
        link.publish_state(State(mission_state="WAIT_FOR_START", flight_mode="HOLD", armed=False))
        link.publish_state(State(mission_state="TAKEOFF", flight_mode="TAKEOFF", armed=True))
        async with observer(broker, T.state) as first:  # wait until the second state is out
            await first.wait_for(lambda: any(b"TAKEOFF" in p for p in first.on(T.state)))
        async with observer(broker, T.online, T.state) as late:
            await late.wait_for(lambda: bool(late.on(T.online)) and bool(late.on(T.state)))
    assert [(t, p, r) for t, p, r in late.messages if t == T.online] == [(T.online, b"true", True)]
    [(_, state, retained)] = [m for m in late.messages if m[0] == T.state]
    assert retained and json.loads(state) == {
        "mission_state": "TAKEOFF", "flight_mode": "TAKEOFF", "armed": True, "outcome": None, "last_error": None,
    }  # fmt: skip


async def test_telemetry_goes_out_at_its_rate_latest_wins(broker: Broker) -> None:
    """20 telemetry samples offered within ~0.1 s at 5 Hz: one per tick goes out (the newest), the rest are counted."""
    link = GroundLink(link_settings(broker, telemetry_rate_hz=5.0), Handler())
    async with running(link), observer(broker, T.telemetry) as obs:
        begin = asyncio.get_running_loop().time()
        for i in range(20):
            link.publish_telemetry(Telemetry(t_s=float(i), position_ned_m=(i, 0.0, -10.0), height_above_sea_m=9.5))
            await asyncio.sleep(0.005)
        ticks = (asyncio.get_running_loop().time() - begin) * 5.0 + 1  # at most this many went out meanwhile
        await obs.wait_for(lambda: any(json.loads(p)["t_s"] == 19.0 for p in obs.on(T.telemetry)))
        await asyncio.sleep(0.5)  # two more ticks: nothing new to send
    sent = obs.json_on(T.telemetry)
    assert sent[-1]["t_s"] == 19.0 and sent[-1]["height_above_sea_m"] == 9.5
    assert len(sent) <= ticks + 1 and link.counters.telemetry_sent == len(sent)
    assert link.counters.telemetry_dropped == 20 - len(sent)


async def test_events_are_sent_in_order(broker: Broker) -> None:
    """Events keep their order and their fields."""
    link = GroundLink(link_settings(broker), Handler())
    async with running(link), observer(broker, T.events) as obs:
        for i in range(5):
            link.publish_event(Event(t_s=float(i), kind="state_changed", fields={"to": f"S{i}", "n": i}))
        await obs.wait_for(lambda: len(obs.on(T.events)) == 5)
    assert [e["fields"] for e in obs.json_on(T.events)] == [{"to": f"S{i}", "n": i} for i in range(5)]


async def test_a_failing_handler_rejects_the_command_and_the_link_keeps_going(broker: Broker) -> None:
    """A handler that raises: the command is rejected as an internal error; the next one still works."""
    calls: list[str] = []

    def handler(command: object) -> str | None:
        calls.append(getattr(command, "id", "?"))
        if len(calls) == 1:
            raise RuntimeError("boom")
        return None

    link = GroundLink(link_settings(broker), handler)
    async with running(link), observer(broker, T.ack) as obs:
        await obs.publish(T.cmd, encode(Start(id="a")))
        await obs.publish(T.cmd, encode(Start(id="b")))
        await obs.wait_for(lambda: len(obs.on(T.ack)) == 2)
    assert [(a["id"], a["accepted"], a["reason"]) for a in obs.json_on(T.ack)] == [
        ("a", False, "internal error: RuntimeError"),
        ("b", True, None),
    ]
