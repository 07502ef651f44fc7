"""Streaming parser for the bytes an X4M03 sends: never raises on bad input; skips and counts it.

``feed(data)`` returns the device messages completed by ``data``. Between packets the parser looks for a
start: ``7D`` (escaped packet) or ``7C 7C 7C 7C`` (NoEscape packet); any other byte is garbage.

Resynchronisation (reference §3.3, made safer): a candidate packet is kept in the buffer until it is
resolved. If it turns out bad — crc mismatch, an unescaped ``7D`` inside it, an impossible length, a
payload that is not a well-formed message (:func:`decode_payload` is strict about lengths, and about float
values, since NoEscape frames carry no checksum) — the parser counts it, drops only its *first* byte and
scans again from the next one. So an intact packet that a bad one swallowed (a truncated frame reads its
length into the next packet) is still found. Candidates are checked byte by byte as they arrive, so a
false start gives way to the packets behind it without waiting for its bogus length to fill up.

Guarantee and its limit: an intact radar frame is always recovered — it starts with 7C 7C 7C 7C, and a
frame body that swallowed any part of that is rejected (a float whose top byte is 0x7C is ~1e36). An
intact *reply* is recovered unless it directly follows a frame that lost exactly its last four bytes and
its own first four bytes read as a plausible float: of the XEP messages only PONG-ready (``7D 01 EA AE``
≈ −2.9e-11) does. That PONG is then lost and the ping times out (the driver retries pings).
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass, fields

import numpy as np

from app.sensors.x4m03_codec import (
    ACK,
    DATA,
    DATA_HEADER_LEN,
    DT_FLOAT,
    END,
    ERROR,
    ESCAPE,
    MAX_ESCAPED_PAYLOAD,
    MAX_FLOATS,
    NOESCAPE_HEADER_LEN,
    NOESCAPE_MAGIC,
    PONG,
    REPLY,
    START,
    SYSTEM,
    DecodeError,
    Message,
    checksum,
    decode_payload,
    plausible_floats,
)

MAX_NOESCAPE_LEN = DATA_HEADER_LEN + 4 * MAX_FLOATS
RESPONSE_CODES = frozenset({ACK, ERROR, PONG, SYSTEM, REPLY, DATA})
_SPECIAL_RE = re.compile(rb"[\x7d-\x7f]")
_START_RE = re.compile(rb"\x7d|\x7c{4}")  # regex escapes: a raw 0x7C is "|"


@dataclass(slots=True)
class ParserStats:
    """What the parser has seen; every skipped byte is counted somewhere."""

    bytes_in: int = 0
    messages: int = 0
    garbage_bytes: int = 0  # bytes outside any packet candidate (and first bytes of rejected candidates)
    crc_errors: int = 0
    bad_packets: int = 0  # right crc or no crc (NoEscape) but not a well-formed message
    bad_lengths: int = 0  # NoEscape length out of range, or an escaped packet longer than the firmware's buffer
    restarts: int = 0  # an unescaped 7D inside an escaped packet

    def as_dict(self) -> dict[str, int]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


class _NeedMore:
    """The candidate may still be a packet: wait for more bytes."""


_NEED_MORE = _NeedMore()
_Result = tuple[Message, int] | _NeedMore | None  # (message, end) | wait | bad


class X4M03Parser:
    """Bytes in, device messages out; keeps at most one unresolved packet in its buffer."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self.stats = ParserStats()

    @property
    def pending_bytes(self) -> int:
        """Bytes held back: the start of a packet not yet resolved."""
        return len(self._buf)

    def reset(self) -> None:
        """Forget held-back bytes (the port was reopened); the counters stay."""
        self._buf.clear()

    def feed(self, data: bytes) -> list[Message]:
        self.stats.bytes_in += len(data)
        self._buf += data
        buf = self._buf
        out: list[Message] = []
        pos = 0
        while True:
            m = _START_RE.search(buf, pos)
            if m is None:
                # Keep a trailing run of up to three 7C: it may be the start of a magic.
                tail = len(buf) - pos
                keep = 0
                while keep < min(3, tail) and buf[len(buf) - 1 - keep] == 0x7C:
                    keep += 1
                self.stats.garbage_bytes += tail - keep
                pos = len(buf) - keep
                break
            start = m.start()
            self.stats.garbage_bytes += start - pos
            result = self._noescape(buf, start) if buf[start] == 0x7C else self._escaped(buf, start)
            if isinstance(result, _NeedMore):
                pos = start
                break
            if result is None:  # bad candidate: drop its first byte, scan on from the next
                self.stats.garbage_bytes += 1
                pos = start + 1
                continue
            message, pos = result
            self.stats.messages += 1
            out.append(message)
        del buf[:pos]
        return out

    def _noescape(self, buf: bytearray, start: int) -> _Result:
        """A NoEscape candidate at ``start``; checked byte by byte as it arrives, so a false start gives way
        to the packets behind it without waiting for its (bogus) length to fill up."""
        len_at = start + len(NOESCAPE_MAGIC)
        n_len = min(4, len(buf) - len_at)
        if n_len <= 0:
            return _NEED_MORE
        # little-endian: the bytes still missing can only make the length larger
        length = int.from_bytes(buf[len_at : len_at + n_len], "little")
        if length > MAX_NOESCAPE_LEN or (n_len == 4 and (length < DATA_HEADER_LEN or (length - DATA_HEADER_LEN) % 4)):
            self.stats.bad_lengths += 1
            return None
        if n_len < 4:
            return _NEED_MORE
        body = start + NOESCAPE_HEADER_LEN
        have = min(len(buf), body + length) - body
        if not self._frame_prefix_ok(buf, body, have, length):
            self.stats.bad_packets += 1
            return None
        if have < length:
            return _NEED_MORE
        try:
            message = decode_payload(bytes(buf[body : body + length]))
        except DecodeError:
            self.stats.bad_packets += 1
            return None
        return message, body + length

    @staticmethod
    def _frame_prefix_ok(buf: bytearray, body: int, have: int, length: int) -> bool:
        """The first ``have`` bytes of a radar-frame payload: A0 12, n matching the length, plausible floats."""
        expected = bytes([DATA, DT_FLOAT]) + bytes(8) + struct.pack("<I", (length - DATA_HEADER_LEN) // 4)
        for k in (0, 1, 10, 11, 12, 13):
            if k < have and buf[body + k] != expected[k]:
                return False
        n_complete = max(0, (have - DATA_HEADER_LEN) // 4)
        if n_complete == 0:
            return True
        start = body + DATA_HEADER_LEN
        return plausible_floats(np.frombuffer(bytes(buf[start : start + 4 * n_complete]), dtype="<f4"))

    def _escaped(self, buf: bytearray, start: int) -> _Result:
        payload = bytearray()
        i = start + 1
        while True:
            m = _SPECIAL_RE.search(buf, i)
            j = len(buf) if m is None else m.start()
            payload += buf[i:j]
            if not self._escaped_prefix_ok(payload):
                return None
            if m is None:
                return _NEED_MORE
            b = buf[j]
            if b == ESCAPE:
                if j + 1 >= len(buf):
                    return _NEED_MORE
                payload.append(buf[j + 1])
                i = j + 2
            elif b == START:
                self.stats.restarts += 1
                return None
            else:  # END
                return self._finish_escaped(bytes(payload), j + 1)

    def _escaped_prefix_ok(self, payload: bytearray) -> bool:
        """Known response code, within the firmware's buffer, and no NoEscape magic inside (no real reply
        holds 7C7C7C7C; a frame behind a false 7D must not wait for a 7E)."""
        if payload and payload[0] not in RESPONSE_CODES:
            self.stats.bad_packets += 1
            return False
        if len(payload) > MAX_ESCAPED_PAYLOAD:
            self.stats.bad_lengths += 1
            return False
        if NOESCAPE_MAGIC in payload:
            self.stats.bad_packets += 1
            return False
        return True

    def _finish_escaped(self, body: bytes, end: int) -> _Result:
        if len(body) < 2:  # at least one payload byte and the crc
            self.stats.bad_packets += 1
            return None
        payload, crc = body[:-1], body[-1]
        if checksum(payload) != crc:
            self.stats.crc_errors += 1
            return None
        try:
            message = decode_payload(payload)
        except DecodeError:
            self.stats.bad_packets += 1
            return None
        return message, end


__all__ = ["END", "ParserStats", "X4M03Parser"]
