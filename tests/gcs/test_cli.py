"""``python -m app.gcs`` as an operator runs it, against a GroundLink on a real broker."""

from __future__ import annotations

import asyncio
import json
import os
import sys
from pathlib import Path

from app.gcs.link import GroundLink
from app.gcs.protocol import AuthorizeLand, Event, Start, State, Topics
from tests.gcs.conftest import Handler, link_settings, running
from tests.gcs.mosquitto import Broker, add_password, free_port, make_test_ca

REPO = Path(__file__).resolve().parents[2]
T = Topics("sea1")


async def gcs(*args: str, env: dict[str, str] | None = None) -> tuple[int, str, str]:
    proc = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "app.gcs", *args, cwd=REPO, env={**os.environ, **(env or {})},
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
    )  # fmt: skip
    out, err = await asyncio.wait_for(proc.communicate(), 30)
    assert proc.returncode is not None
    return proc.returncode, out.decode(), err.decode()


async def test_start_is_acked_accepted_printed_in_one_line_exit_0(broker: Broker) -> None:
    """start with a search point and radius: the handler gets them, the CLI prints the ack and exits 0."""
    handler = Handler()
    async with running(GroundLink(link_settings(broker), handler)):
        code, out, err = await gcs(
            "start", "--broker", broker.url, "--vehicle-id", "sea1", "--id", "op-1",
            "--start-ne", "12.5", "-3", "--search-radius", "25",
        )  # fmt: skip
    assert (code, err) == (0, "")
    assert out.count("\n") == 1 and json.loads(out) == {"id": "op-1", "cmd": "start", "accepted": True, "reason": None}
    assert handler.received == [Start(id="op-1", start_ne_m=(12.5, -3.0), search_radius_m=25.0)]


async def test_a_rejected_command_prints_the_reason_exit_1(broker: Broker) -> None:
    """authorize-land refused by the vehicle: the ack with its reason, exit 1."""
    handler = Handler(reason="pilot has control")
    async with running(GroundLink(link_settings(broker), handler)):
        code, out, _ = await gcs("authorize-land", "--broker", broker.url, "--vehicle-id", "sea1", "--id", "L")
    assert code == 1
    assert json.loads(out) == {"id": "L", "cmd": "authorize_land", "accepted": False, "reason": "pilot has control"}
    assert handler.received == [AuthorizeLand(id="L")]


async def test_no_vehicle_listening_is_a_timeout_exit_1(broker: Broker) -> None:
    """Nobody answers: one line on stderr naming the command and id, exit 1."""
    code, out, err = await gcs(
        "abort", "--broker", broker.url, "--vehicle-id", "sea1", "--id", "a1", "--timeout", "0.5"
    )
    assert (code, out) == (1, "")
    assert err == "python -m app.gcs: no ack for abort id a1 within 0.5 s\n"


async def test_an_unreachable_broker_is_one_line_exit_1() -> None:
    """Connection refused: one line naming the broker, exit 1."""
    url = f"mqtt://127.0.0.1:{free_port()}"
    code, _, err = await gcs("hold", "--broker", url, "--vehicle-id", "sea1")
    assert code == 1 and err.startswith(f"python -m app.gcs: {url}: ") and err.count("\n") == 1


async def test_bad_input_is_one_line_exit_2() -> None:
    """Bad URL, options that do not go with the command, a bad id, an unset password variable: exit 2, one line."""
    cases = {
        ("rtl", "--broker", "http://h", "--vehicle-id", "sea1"): "--broker: must start with mqtt:// or mqtts://",
        ("rtl", "--broker", "mqtt://h", "--vehicle-id", "a/b"): "--vehicle-id: 1–64 characters",
        ("abort", "--broker", "mqtt://h", "--vehicle-id", "v", "--start-ne", "1", "2"): "go with start only",
        ("abort", "--broker", "mqtt://h", "--vehicle-id", "v", "--id", "x" * 65): "--id: String should have at most",
        ("start", "--broker", "mqtt://h", "--vehicle-id", "v", "--search-radius", "-1"): "outside 0.1..5000 m",
        ("hold", "--broker", "mqtt://h", "--vehicle-id", "v", "--username", "u", "--password-env", "NO_SUCH_VAR_X"): (
            "--password-env: variable NO_SUCH_VAR_X is not set"
        ),
        ("fly", "--broker", "mqtt://h", "--vehicle-id", "v"): "invalid choice: 'fly'",
    }
    results = await asyncio.gather(*(gcs(*args) for args in cases))
    for (args, expected), (code, out, err) in zip(cases.items(), results, strict=True):
        assert (code, out) == (2, ""), args
        assert err.startswith("python -m app.gcs: error: ") and err.count("\n") == 1, err
        assert expected in err, (expected, err)


async def test_watch_prints_state_events_and_online_one_line_each(broker: Broker) -> None:
    """watch: the retained online and state at once, then each event as it comes, one line each."""
    link = GroundLink(link_settings(broker), Handler())
    async with running(link):
        link.publish_state(State(mission_state="WAIT_FOR_START", flight_mode="HOLD", armed=False))
        proc = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "app.gcs", "watch", "--broker", broker.url, "--vehicle-id", "sea1",
            "--timeout", "20", cwd=REPO, stdout=asyncio.subprocess.PIPE,
        )  # fmt: skip
        assert proc.stdout is not None
        lines: list[str] = []
        try:
            async with asyncio.timeout(10):
                while not (any(x.startswith("state ") for x in lines) and "online true" in lines):
                    lines.append((await proc.stdout.readline()).decode().rstrip("\n"))
                link.publish_event(Event(t_s=3.5, kind="target_found", fields={"range_m": 4.2}))
                lines.append((await proc.stdout.readline()).decode().rstrip("\n"))
        finally:
            proc.kill()
            await proc.wait()
    state = next(x for x in lines if x.startswith("state "))
    assert json.loads(state.removeprefix("state "))["mission_state"] == "WAIT_FOR_START"
    assert lines[-1].startswith("event ")
    assert json.loads(lines[-1].removeprefix("event ")) == {
        "t_s": 3.5,
        "kind": "target_found",
        "fields": {"range_m": 4.2},
    }


async def test_over_tls_with_a_password(tmp_path: Path) -> None:
    """--ca, --username and --password-env: the command goes through an authenticating TLS broker."""
    ca, cert, key = make_test_ca(tmp_path)
    add_password(tmp_path / "passwd", "op", "pw-1")
    add_password(tmp_path / "passwd", "uav", "pw-2")
    broker = Broker(tmp_path, password_file=tmp_path / "passwd", tls=(ca, cert, key))
    broker.start()
    handler = Handler()
    settings = link_settings(broker, ca_file=str(ca), username="uav", password_env="UAV_PW")
    try:
        async with running(GroundLink(settings, handler, environ={"UAV_PW": "pw-2"})):
            code, out, err = await gcs(
                "resume", "--broker", broker.url, "--vehicle-id", "sea1", "--id", "r1", "--ca", str(ca),
                "--username", "op", "--password-env", "OP_PW", env={"OP_PW": "pw-1"},
            )  # fmt: skip
            bad = await gcs(
                "resume", "--broker", broker.url, "--vehicle-id", "sea1", "--ca", str(ca),
                "--username", "op", "--password-env", "OP_PW", env={"OP_PW": "wrong"},
            )  # fmt: skip
    finally:
        broker.stop()
    assert (code, err) == (0, "") and json.loads(out)["accepted"] is True
    assert bad[0] == 1 and "ot authori" in bad[2]
    assert [c.id for c in handler.received] == ["r1"]
