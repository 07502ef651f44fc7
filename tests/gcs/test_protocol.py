"""The payloads: strict command parsing with errors that name the problem; topics; what goes out."""

from __future__ import annotations

import json
import math

import pytest

from app.gcs.protocol import (
    MAX_COMMAND_BYTES,
    Abort,
    AuthorizeLand,
    Hold,
    MalformedCommand,
    Resume,
    Rtl,
    Start,
    Telemetry,
    Topics,
    encode,
    parse_command,
)


@pytest.mark.parametrize(
    ("payload", "command"),
    [
        (b'{"cmd":"start","id":"1"}', Start(id="1")),
        (
            b'{"id":"s","cmd":"start","start_ne_m":[1,-2.5],"search_radius_m":40}',
            Start(id="s", start_ne_m=(1, -2.5), search_radius_m=40),
        ),
        (b'{"cmd":"abort","id":"a"}', Abort(id="a")),
        (b'{"cmd":"hold","id":"h"}', Hold(id="h")),
        (b'{"cmd":"resume","id":"r"}', Resume(id="r")),
        (b'{"cmd":"rtl","id":"t"}', Rtl(id="t")),
        ('{"cmd":"authorize_land","id":"landé-1"}'.encode(), AuthorizeLand(id="landé-1")),
    ],
)
def test_each_command_parses_to_its_model(payload: bytes, command: object) -> None:
    """Every command of the protocol, with its optional fields."""
    assert parse_command(payload) == command


@pytest.mark.parametrize(
    ("payload", "reason", "cmd_id", "cmd"),
    [
        (b"{nope", "not valid JSON at line 1 column 2", None, None),
        (b"\xff\xfe{}", "payload is not UTF-8 text (byte 0)", None, None),
        (b'{"cmd":"abort","id":"' + b"x" * MAX_COMMAND_BYTES + b'"}', "at most 4096", None, None),
        (b"[]", "payload must be a JSON object, got an array", None, None),
        (b'{"id":"q"}', "missing field 'cmd'", "q", None),
        (b'{"cmd":"fly","id":"q"}', 'unknown command "fly" (one of: start, abort', "q", None),
        (b'{"cmd":7,"id":"q"}', "cmd must be a string naming a command, got a number", "q", None),
        (b'{"cmd":"rtl"}', "id: Field required", None, "rtl"),
        (b'{"cmd":"rtl","id":""}', "id: String should have at least 1 character", None, "rtl"),
        (b'{"cmd":"rtl","id":5}', "id: Input should be a valid string (got 5)", None, "rtl"),
        (b'{"cmd":"rtl","id":"a\\nb"}', "id: control characters are not allowed", None, "rtl"),
        (b'{"cmd":"rtl","id":"' + b"i" * 65 + b'"}', "id: String should have at most 64 characters", None, "rtl"),
        (b'{"cmd":"rtl","id":"q","to":"home"}', 'unknown field "to" for rtl (its fields: cmd, id)', "q", "rtl"),
        (b'{"cmd":"rtl","id":"q","id":"r"}', 'duplicate key "id"', None, None),
        (
            b'{"cmd":"start","id":"q","search_radius_m":"5"}',
            'search_radius_m: Input should be a valid number (got "5")',
            "q",
            "start",
        ),
        (
            b'{"cmd":"start","id":"q","search_radius_m":true}',
            "search_radius_m: Input should be a valid number (got true)",
            "q",
            "start",
        ),
        (
            b'{"cmd":"start","id":"q","search_radius_m":0}',
            "search_radius_m: Input should be greater than 0",
            "q",
            "start",
        ),
        (
            b'{"cmd":"start","id":"q","search_radius_m":1e999}',
            "search_radius_m: Input should be a finite number",
            "q",
            "start",
        ),
        (b'{"cmd":"start","id":"q","search_radius_m":NaN}', "NaN is not a JSON number", None, None),
        (b'{"cmd":"start","id":"q","start_ne_m":[1]}', "start_ne_m.1: Field required", "q", "start"),
        (
            b'{"cmd":"start","id":"q","start_ne_m":[1,2,3]}',
            "start_ne_m: Tuple should have at most 2 items",
            "q",
            "start",
        ),
        (
            b'{"cmd":"start","id":"q","start_ne_m":[1,20000]}',
            "start_ne_m.1: Input should be less than or equal to 10000",
            "q",
            "start",
        ),
        (b'{"cmd":"abort","id":"\\ud800"}', "not valid JSON", None, "abort"),
        (b"[" * 3000, "not valid JSON", None, None),
    ],
)
def test_a_malformed_command_raises_an_error_naming_the_problem(
    payload: bytes, reason: str, cmd_id: str | None, cmd: str | None
) -> None:
    """Each kind of bad payload: the reason says what is wrong; id and cmd are kept when readable."""
    with pytest.raises(MalformedCommand) as caught:
        parse_command(payload)
    assert reason in caught.value.reason
    assert (caught.value.cmd_id, caught.value.cmd) == (cmd_id, cmd)
    assert len(caught.value.reason) < 300  # the reason goes into an ack: never an echo of a huge payload


def test_topics_are_versioned_under_the_vehicle_and_ids_are_checked() -> None:
    """seapick/<vehicle>/v1/…; a vehicle id that would break the topic tree is refused."""
    t = Topics("sea-1")
    assert (t.cmd, t.ack, t.state, t.telemetry, t.events, t.online) == (
        "seapick/sea-1/v1/cmd", "seapick/sea-1/v1/cmd/ack", "seapick/sea-1/v1/state",
        "seapick/sea-1/v1/telemetry", "seapick/sea-1/v1/events", "seapick/sea-1/v1/online",
    )  # fmt: skip
    for bad in ("", "a/b", "a+", "#", "x" * 65):
        with pytest.raises(ValueError, match="vehicle id"):
            Topics(bad)


def test_a_command_encoded_parses_back_to_itself() -> None:
    """What the CLI sends is what the vehicle reads."""
    start = Start(id="z", start_ne_m=(3.0, 4.0), search_radius_m=12.0)
    assert parse_command(encode(start)) == start


def test_telemetry_encodes_non_finite_numbers_as_null() -> None:
    """A NaN height (radar lost) goes out as null, valid JSON."""
    t = Telemetry(t_s=1.0, position_ned_m=(1.0, 2.0, -3.0), height_above_sea_m=math.nan)
    assert json.loads(encode(t))["height_above_sea_m"] is None
