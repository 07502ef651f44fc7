"""The X4M03 codec against the reference's test vectors (reference/x4m03-protocol.md §4–§6)."""

from __future__ import annotations

import numpy as np
import pytest

from app.sensors import x4m03_commands as cmd
from app.sensors.x4m03_codec import (
    DT_BYTE,
    DT_FLOAT,
    DT_INT,
    PONG_READY,
    SYSTEM_BOOTING,
    SYSTEM_READY,
    Ack,
    DataFloat,
    DecodeError,
    ErrorReply,
    Pong,
    Reply,
    SystemMessage,
    ack_payload,
    data_float_payload,
    decode_payload,
    encode_noescape,
    encode_packet,
    error_payload,
    pong_payload,
    reply_payload,
    system_payload,
)
from app.sensors.x4m03_commands import X4Param
from app.sensors.x4m03_frame_area import BASEBAND_BIN_M, quantise_frame_area
from app.sensors.x4m03_parser import X4M03Parser


def h(text: str) -> bytes:
    return bytes.fromhex(text)


COMMAND_VECTORS = [
    (cmd.ping(), "7D 01 AE EA AA EE 7C 7E"),
    (cmd.module_reset(), "7D 22 5F 7E"),
    (cmd.x4driver_init(), "7D 50 20 0D 7E"),
    (cmd.x4_set(X4Param.DOWNCONVERSION, 1), "7D 50 10 13 00 00 00 01 2F 7E"),
    (cmd.x4_set(X4Param.DAC_MIN, 949), "7D 50 10 16 00 00 00 B5 03 00 00 9D 7E"),
    (cmd.x4_set(X4Param.DAC_MAX, 1100), "7D 50 10 17 00 00 00 4C 04 00 00 62 7E"),
    (cmd.x4_set(X4Param.ITERATIONS, 16), "7D 50 10 12 00 00 00 10 00 00 00 3F 7E"),
    (cmd.x4_set(X4Param.PULSES_PER_STEP, 300), "7D 50 10 11 00 00 00 2C 01 00 00 01 7E"),
    (cmd.x4_set(X4Param.TX_CENTER_FREQUENCY, 3), "7D 50 10 20 00 00 00 03 1E 7E"),
    (cmd.x4_set(X4Param.TX_POWER, 2), "7D 50 10 21 00 00 00 02 1E 7E"),
    (cmd.x4_set(X4Param.FRAME_AREA_OFFSET, 0.18), "7D 50 10 18 00 00 00 EC 51 38 3E 9E 7E"),
    (cmd.x4_set(X4Param.FRAME_AREA, 0.4, 5.0), "7D 50 10 14 00 00 00 CD CC CC 3E 00 00 A0 40 3A 7E"),
    (cmd.x4_set(X4Param.FPS, 10.0), "7D 50 10 10 00 00 00 00 00 20 41 4C 7E"),
    (cmd.x4_set(X4Param.FPS, 0.0), "7D 50 10 10 00 00 00 00 00 00 00 2D 7E"),
    (cmd.x4_get(X4Param.FRAME_AREA), "7D 50 11 14 00 00 00 28 7E"),
    (cmd.x4_get(X4Param.FRAME_AREA_OFFSET), "7D 50 11 18 00 00 00 24 7E"),
    (cmd.x4_get(X4Param.FPS), "7D 50 11 10 00 00 00 2C 7E"),
    (cmd.x4_get(X4Param.ITERATIONS), "7D 50 11 12 00 00 00 2E 7E"),
    (cmd.x4_get(X4Param.FRAME_BIN_COUNT), "7D 50 11 26 00 00 00 1A 7E"),
    (cmd.get_system_info(2), "7D 90 58 02 B7 7E"),
    (cmd.set_sensor_mode(0x13), "7D 20 13 4E 7E"),
    (cmd.set_sensor_mode(0x12), "7D 20 12 4F 7E"),
]


@pytest.mark.parametrize(("payload", "wire"), COMMAND_VECTORS, ids=[w for _, w in COMMAND_VECTORS])
def test_host_commands_encode_to_the_reference_bytes(payload, wire):
    assert encode_packet(payload) == h(wire)


DEVICE_VECTORS = [
    (ack_payload(), "7D 10 6D 7E", Ack()),
    (system_payload(SYSTEM_BOOTING), "7D 30 10 00 00 00 5D 7E", SystemMessage(SYSTEM_BOOTING)),
    (system_payload(SYSTEM_READY), "7D 30 11 00 00 00 5C 7E", SystemMessage(SYSTEM_READY)),
    (error_payload(1), "7D 20 01 00 00 00 5C 7E", ErrorReply(1)),
    (pong_payload(PONG_READY), "7D 01 EA AE EE AA 7C 7E", Pong(PONG_READY)),
]


@pytest.mark.parametrize(("payload", "wire", "message"), DEVICE_VECTORS, ids=[w for _, w, _ in DEVICE_VECTORS])
def test_device_messages_encode_and_parse_as_the_reference_says(payload, wire, message):
    assert encode_packet(payload) == h(wire)
    assert X4M03Parser().feed(h(wire)) == [message]


def test_frame_area_reply_has_an_escaped_end_byte_inside_a_float_and_decodes_to_the_quantised_area():
    axis = quantise_frame_area(0.4, 5.0, 0.18)
    wire = h("7D 11 12 14 00 00 00 00 00 00 00 02 00 00 00 82 82 C5 3E 15 7F 7E A0 40 04 1C 7E")
    assert encode_packet(reply_payload(DT_FLOAT, X4Param.FRAME_AREA, [axis.start_m, axis.end_m])) == wire
    [reply] = X4M03Parser().feed(wire)
    assert isinstance(reply, Reply) and reply.content_id == X4Param.FRAME_AREA
    assert reply.values == pytest.approx((0.38576132, 5.0153909), abs=1e-7)


def test_fps_and_bin_count_replies_match_the_reference():
    fps = h("7D 11 12 10 00 00 00 00 00 00 00 01 00 00 00 4A 83 20 41 04 C3 7E")
    bins = h("7D 11 11 26 00 00 00 00 00 00 00 01 00 00 00 5B 00 00 00 01 7E")
    assert encode_packet(reply_payload(DT_FLOAT, X4Param.FPS, [10.032052556])) == fps
    assert encode_packet(reply_payload(DT_INT, X4Param.FRAME_BIN_COUNT, [91])) == bins
    parsed = X4M03Parser().feed(fps + bins)
    assert parsed[0].values == pytest.approx((10.032052556,), rel=1e-7)
    assert parsed[1] == Reply(DT_INT, X4Param.FRAME_BIN_COUNT, 0, (91,))


def test_byte_reply_trailer_is_ignored():
    [reply] = X4M03Parser().feed(encode_packet(reply_payload(DT_BYTE, X4Param.TX_POWER, b"\x02")))
    assert reply == Reply(DT_BYTE, X4Param.TX_POWER, 0, b"\x02")


def test_noescape_radar_frame_header_matches_the_reference_and_round_trips():
    values = np.linspace(-0.01, 0.01, 182, dtype=np.float32)
    wire = encode_noescape(data_float_payload(1234, values))
    assert wire[:23] == h("7C 7C 7C 7C E6 02 00 00 00 A0 12 00 00 00 00 D2 04 00 00 B6 00 00 00")
    assert len(wire) == 751
    assert X4M03Parser().feed(wire) == [DataFloat(0, 1234, values)]


def test_legacy_escaped_radar_frame_is_accepted_too():
    values = np.full(8, 0.0123, dtype=np.float32)
    assert X4M03Parser().feed(encode_packet(data_float_payload(7, values))) == [DataFloat(0, 7, values)]


@pytest.mark.parametrize(
    ("payload", "why"),
    [
        (b"", "empty"),
        (b"\x10\x00", "ACK must be 1 byte"),
        (b"\x20\x01\x00\x00", "ERROR must be 5 bytes"),
        (b"\x42", "unknown response code"),
        (data_float_payload(1, np.zeros(4))[:-4], "says 4 floats"),
        (data_float_payload(1, np.array([0.1, np.nan])), "implausible"),
        (data_float_payload(1, np.array([0.1, 3e36])), "implausible"),
    ],
)
def test_malformed_payloads_are_refused_with_a_reason(payload, why):
    with pytest.raises(DecodeError, match=why):
        decode_payload(payload)


@pytest.mark.parametrize(
    ("area", "bins", "start_m", "end_m"),
    [
        ((0.4, 5.0, 0.18), 91, 0.385761, 5.015391),
        ((0.35, 3.0, 0.18), 53, 0.334321, None),
        ((-0.5, 5.0, 0.18), 107, -0.437284, None),
    ],
)
def test_frame_area_quantisation_reproduces_the_firmware(area, bins, start_m, end_m):
    axis = quantise_frame_area(*area)
    assert axis.bins == bins
    assert axis.start_m == pytest.approx(start_m, abs=1e-6)
    assert axis.bin_m == pytest.approx(0.0514403, abs=1e-7) == BASEBAND_BIN_M
    if end_m is not None:
        assert axis.end_m == pytest.approx(end_m, abs=1e-6)


def test_frame_area_with_start_after_end_is_refused():
    with pytest.raises(ValueError, match="after its end"):
        quantise_frame_area(3.0, 1.0, 0.18)


def test_set_with_the_wrong_number_of_values_is_refused():
    with pytest.raises(ValueError, match="FRAME_AREA takes 2"):
        cmd.x4_set(X4Param.FRAME_AREA, 0.4)
