"""The streaming parser: random and corrupted byte streams never raise, and every intact packet comes through."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from app.sensors.x4m03_codec import (
    DT_BYTE,
    DT_FLOAT,
    DT_INT,
    PONG_NOT_READY,
    PONG_READY,
    SYSTEM_BOOTING,
    SYSTEM_READY,
    DataFloat,
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
from app.sensors.x4m03_parser import MAX_NOESCAPE_LEN, X4M03Parser

# Radar values as the device sends them: |v| up to ~1.4, often tiny, sometimes exactly 0.
radar_value = st.one_of(
    st.just(0.0),
    st.floats(1e-6, 1.4).flatmap(lambda v: st.sampled_from([v, -v])),
)


@st.composite
def radar_frame(draw) -> bytes:
    n = draw(st.integers(0, 24))
    values = np.array(draw(st.lists(radar_value, min_size=n, max_size=n)), dtype=np.float32)
    payload = data_float_payload(draw(st.integers(0, 2**32 - 1)), values)
    return encode_packet(payload) if draw(st.booleans()) and n < 8 else encode_noescape(payload)


params = st.sampled_from(list(X4Param))
device_packet = st.one_of(
    radar_frame(),
    radar_frame(),
    st.just(encode_packet(ack_payload())),
    st.integers(1, 0x22).map(lambda c: encode_packet(error_payload(c))),
    st.sampled_from([PONG_READY, PONG_NOT_READY]).map(lambda v: encode_packet(pong_payload(v))),
    st.sampled_from([SYSTEM_BOOTING, SYSTEM_READY]).map(lambda c: encode_packet(system_payload(c))),
    st.tuples(params, st.lists(st.floats(0.01, 20.0), min_size=1, max_size=2)).map(
        lambda a: encode_packet(reply_payload(DT_FLOAT, a[0], a[1]))
    ),
    st.tuples(params, st.integers(-(2**31), 2**31 - 1)).map(
        lambda a: encode_packet(reply_payload(DT_INT, a[0], [a[1]]))
    ),
    st.tuples(params, st.binary(min_size=1, max_size=3)).map(
        lambda a: encode_packet(reply_payload(DT_BYTE, a[0], a[1]))
    ),
)


@st.composite
def corrupted(draw, packet: st.SearchStrategy[bytes]) -> bytes:
    """A packet with bytes dropped, changed, or its tail cut off."""
    wire = bytearray(draw(packet))
    kind = draw(st.sampled_from(["drop", "flip", "cut"]))
    i = draw(st.integers(0, len(wire) - 1))
    if kind == "drop":
        del wire[i : i + draw(st.integers(1, 8))]
    elif kind == "flip":
        wire[i] ^= draw(st.integers(1, 255))
    else:
        del wire[i:]
    return bytes(wire)


# An item of the stream: ("frame"/"reply", bytes) must come out; ("noise", bytes) may produce anything or nothing.
stream_item = st.one_of(
    radar_frame().map(lambda b: ("frame", b)),
    device_packet.map(lambda b: ("frame" if b[0] == 0x7C else "reply", b)),
    st.binary(min_size=1, max_size=40).map(lambda b: ("noise", b)),
    st.sampled_from([b"\x7c\x7c\x7c", b"\x7c" * 6, b"\x7d", b"\x7e", b"\x7f"]).map(lambda b: ("noise", b)),
    corrupted(device_packet).map(lambda b: ("corrupt", b)),
)


def must_come_out(items: list[tuple[str, bytes]]) -> list[bytes]:
    """Every intact frame; every intact reply except one right behind a corrupted packet (see the parser's
    docstring: a frame short by 4 bytes can take a PONG's first bytes for its last float)."""
    keep = []
    for k, (kind, b) in enumerate(items):
        if kind == "frame" or (kind == "reply" and (k == 0 or items[k - 1][0] != "corrupt")):
            keep.append(b)
    return keep


def feed_in_chunks(parser: X4M03Parser, data: bytes, cuts: list[int]) -> list:
    out, last = [], 0
    for cut in [*sorted({c % (len(data) + 1) for c in cuts}), len(data)]:
        out += parser.feed(data[last:cut])
        last = cut
    return out


def is_subsequence(needles: list, haystack: list) -> bool:
    it = iter(haystack)
    return all(any(n == h for h in it) for n in needles)


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(items=st.lists(stream_item, max_size=20), cuts=st.lists(st.integers(0, 10_000), max_size=12))
def test_every_intact_frame_inside_noise_and_corruption_is_recovered_in_order(items, cuts):
    parser = X4M03Parser()
    data = b"".join(b for _, b in items)
    messages = feed_in_chunks(parser, data, cuts)
    expected = [X4M03Parser().feed(b)[0] for b in must_come_out(items)]
    assert is_subsequence(expected, messages), (expected, messages)
    assert parser.stats.bytes_in == len(data)


@settings(max_examples=300, deadline=None)
@given(data=st.binary(max_size=3000), cuts=st.lists(st.integers(0, 3000), max_size=20))
def test_random_bytes_never_raise_and_every_byte_is_accounted_for(data, cuts):
    parser = X4M03Parser()
    messages = feed_in_chunks(parser, data, cuts)
    s = parser.stats
    assert s.bytes_in == len(data)
    assert parser.pending_bytes <= MAX_NOESCAPE_LEN + 9  # at most one unresolved packet is held back
    if b"\x7c" not in data and b"\x7d" not in data:  # no packet can start: all of it is garbage
        assert messages == [] and s.garbage_bytes == len(data)


def test_garbage_between_frames_is_skipped_counted_and_the_frames_survive():
    frames = [np.full(182, 0.001 * (k + 1), dtype=np.float32) for k in range(3)]
    wire = [encode_noescape(data_float_payload(k, f)) for k, f in enumerate(frames)]
    garbage = bytes(range(0x20, 0x40))
    parser = X4M03Parser()
    out = parser.feed(garbage + wire[0] + garbage + wire[1] + b"\x7c\x7c\x7c" + wire[2])
    assert out == [DataFloat(0, k, f) for k, f in enumerate(frames)]
    assert parser.stats.garbage_bytes == 2 * len(garbage) + 3


def test_a_bad_crc_is_counted_and_the_next_packet_still_parses():
    bad = bytearray(encode_packet(error_payload(1)))
    bad[-2] ^= 0x01
    parser = X4M03Parser()
    out = parser.feed(bytes(bad) + encode_packet(ack_payload()))
    assert out == [decode_payload(ack_payload())]
    assert parser.stats.crc_errors == 1


def test_a_truncated_frame_does_not_swallow_the_ack_and_frame_behind_it():
    frame = encode_noescape(data_float_payload(5, np.full(182, 0.01, dtype=np.float32)))
    truncated = frame[:300]  # its length field still says 742 bytes
    after = encode_packet(ack_payload()) + encode_noescape(data_float_payload(6, np.full(182, 0.02, dtype=np.float32)))
    parser = X4M03Parser()
    out = parser.feed(truncated + after)
    assert [type(m).__name__ for m in out] == ["Ack", "DataFloat"]
    assert out[1].frame_counter == 6
    assert parser.stats.bad_packets >= 1


def test_a_frame_split_across_many_feeds_is_delivered_once_complete():
    wire = encode_noescape(data_float_payload(9, np.full(182, 0.5, dtype=np.float32)))
    parser = X4M03Parser()
    outs = [parser.feed(wire[i : i + 7]) for i in range(0, len(wire), 7)]
    assert [len(o) for o in outs[:-1]] == [0] * (len(outs) - 1)
    assert outs[-1][0].frame_counter == 9
