"""X4M03 (XEP firmware 3.x) wire format: escaped packets, NoEscape radar frames and the device's messages.

Everything here follows ``reference/x4m03-protocol.md`` §3, §5 and §6; all integers little-endian, floats
IEEE-754 float32 little-endian.

Escaped packet (both directions)::

    7D | esc(payload) | esc(crc) | 7E        crc = 0x7D ^ p[0] ^ … ^ p[n-1]   (over the *unescaped* payload)
    esc(b) = 7F b  if b ∈ {7D, 7E, 7F}  else  b                     (the byte is prefixed, not changed)

NoEscape packet (device → host, radar frames on XEP 3.x)::

    7C 7C 7C 7C | u32 len | u8 crc (0, unused) | payload[len]          (no end byte)

Device messages dispatch on ``payload[0]``: ACK 0x10, ERROR 0x20, PONG 0x01, SYSTEM 0x30, REPLY 0x11 and
DATA 0xA0 (radar frame: ``A0 12 | u32 content_id | u32 frame_counter | u32 n | f32[n]``).
:func:`decode_payload` is strict — exact lengths, plausible floats — because the NoEscape framing has no
checksum: the parser relies on it to reject garbage that merely looks like a packet.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Final

import numpy as np

START: Final = 0x7D
END: Final = 0x7E
ESCAPE: Final = 0x7F
SPECIAL: Final = frozenset({START, END, ESCAPE})
NOESCAPE_MAGIC: Final = b"\x7c\x7c\x7c\x7c"
NOESCAPE_HEADER_LEN: Final = 9  # magic, u32 len, u8 crc

# Response codes (payload[0] of a device message)
PONG: Final = 0x01
ACK: Final = 0x10
REPLY: Final = 0x11
ERROR: Final = 0x20
SYSTEM: Final = 0x30
DATA: Final = 0xA0

# Data types of REPLY and DATA messages, with their element size in bytes
DT_BYTE: Final = 0x10
DT_INT: Final = 0x11
DT_FLOAT: Final = 0x12
DT_STRING: Final = 0x13
ELEMENT_SIZE: Final = {DT_BYTE: 1, DT_INT: 4, DT_FLOAT: 4, DT_STRING: 1}
# The firmware appends the element size after BYTE/STRING/FLOAT replies (not INT) — §5 "REPLY quirk"
REPLY_TRAILER: Final = {DT_BYTE: 1, DT_FLOAT: 4, DT_STRING: 1}

PONG_READY: Final = 0xAAEEAEEA
PONG_NOT_READY: Final = 0xAEEAEEAA
PONG_SAFE_MODE: Final = 0xFFEEFEEF
SYSTEM_BOOTING: Final = 0x10
SYSTEM_READY: Final = 0x11

DATA_HEADER_LEN: Final = 14  # A0 12 | content_id | info | n
MAX_FLOATS: Final = 1536  # RF mode: at most 1536 samples (9.88 m at 6.43 mm); baseband: 2·192
MAX_ESCAPED_PAYLOAD: Final = 8000  # the firmware's receive buffer
# Sanity limits for float values in a radar frame. Real values are ~1e-5 … 1.414 (|I + jQ| max); a float
# outside them (or NaN/inf) means the bytes are not a frame. Exact zeros are allowed.
MAX_ABS_FLOAT: Final = 1e3
MIN_ABS_FLOAT: Final = 1e-12


class DecodeError(ValueError):
    """Raised by :func:`decode_payload` when a payload is not a well-formed device message."""


# --------------------------------------------------------------------------------------------- encoding


def checksum(payload: bytes) -> int:
    """crc = 0x7D XOR every (unescaped) payload byte."""
    crc = START
    for b in payload:
        crc ^= b
    return crc


def _escape(data: bytes) -> bytes:
    out = bytearray()
    for b in data:
        if b in SPECIAL:
            out.append(ESCAPE)
        out.append(b)
    return bytes(out)


def encode_packet(payload: bytes) -> bytes:
    """The escaped packet ``7D | esc(payload) | esc(crc) | 7E``."""
    return bytes([START]) + _escape(payload + bytes([checksum(payload)])) + bytes([END])


def encode_noescape(payload: bytes) -> bytes:
    """The NoEscape packet ``7C 7C 7C 7C | u32 len | 00 | payload``."""
    return NOESCAPE_MAGIC + struct.pack("<IB", len(payload), 0) + payload


def data_float_payload(frame_counter: int, values: np.ndarray, content_id: int = 0) -> bytes:
    """``A0 12 | u32 content_id | u32 frame_counter | u32 n | f32[n]`` (a radar frame's payload)."""
    floats = np.asarray(values, dtype="<f4")
    return struct.pack("<BBIII", DATA, DT_FLOAT, content_id, frame_counter, floats.size) + floats.tobytes()


def ack_payload() -> bytes:
    return bytes([ACK])


def error_payload(code: int) -> bytes:
    return struct.pack("<Bi", ERROR, code)


def pong_payload(value: int = PONG_READY) -> bytes:
    return struct.pack("<BI", PONG, value)


def system_payload(code: int) -> bytes:
    return struct.pack("<BI", SYSTEM, code)


def reply_payload(datatype: int, content_id: int, values: bytes | list[int] | list[float], info: int = 0) -> bytes:
    """A REPLY as the firmware builds it, including its trailing element-size byte (not after INT)."""
    if datatype == DT_FLOAT:
        body = np.asarray(values, dtype="<f4").tobytes()
    elif datatype == DT_INT:
        body = np.asarray(values, dtype="<i4").tobytes()
    else:
        body = bytes(values)  # type: ignore[arg-type]
    count = len(body) // ELEMENT_SIZE[datatype]
    trailer = bytes([REPLY_TRAILER[datatype]]) if datatype in REPLY_TRAILER else b""
    return struct.pack("<BBIII", REPLY, datatype, content_id, info, count) + body + trailer


# --------------------------------------------------------------------------------------------- messages


@dataclass(frozen=True, slots=True)
class Ack:
    """The command was accepted."""


@dataclass(frozen=True, slots=True)
class ErrorReply:
    """The command was refused; ``code`` is the MCP or x4driver status (1 = not recognised / NOK)."""

    code: int


@dataclass(frozen=True, slots=True)
class Pong:
    value: int

    @property
    def ready(self) -> bool:
        return self.value == PONG_READY


@dataclass(frozen=True, slots=True)
class SystemMessage:
    """BOOTING (0x10) after power-up or reset, READY (0x11) once initialised."""

    code: int


@dataclass(frozen=True, slots=True)
class Reply:
    """The answer to a GET: ``content_id`` is the queried parameter ID; ``values`` already decoded."""

    datatype: int
    content_id: int
    info: int
    values: tuple[float, ...] | tuple[int, ...] | bytes


@dataclass(frozen=True, slots=True, eq=False)
class DataFloat:
    """A radar frame: ``values`` as sent (downconversion 1: I block, then Q block)."""

    content_id: int
    frame_counter: int
    values: np.ndarray  # float32, shape (n,)

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, DataFloat)
            and (self.content_id, self.frame_counter) == (other.content_id, other.frame_counter)
            and np.array_equal(self.values, other.values)
        )

    __hash__ = None  # type: ignore[assignment]


Message = Ack | ErrorReply | Pong | SystemMessage | Reply | DataFloat


# --------------------------------------------------------------------------------------------- decoding


def _exact(payload: bytes, n: int, name: str) -> None:
    if len(payload) != n:
        raise DecodeError(f"{name} must be {n} bytes, got {len(payload)}")


def plausible_floats(values: np.ndarray) -> bool:
    """True when every value could come from the radar: finite, |v| ≤ 1e3, and 0 or |v| ≥ 1e-12."""
    with np.errstate(invalid="ignore", over="ignore"):
        a = np.abs(values.astype(np.float64))
        return bool(np.all((a <= MAX_ABS_FLOAT) & ((a >= MIN_ABS_FLOAT) | (a == 0.0))))


def decode_payload(payload: bytes) -> Message:
    """The device message in ``payload`` (unescaped, without crc); raises DecodeError when malformed."""
    if not payload:
        raise DecodeError("empty payload")
    code = payload[0]
    if code == ACK:
        _exact(payload, 1, "ACK")
        return Ack()
    if code == ERROR:
        _exact(payload, 5, "ERROR")
        return ErrorReply(struct.unpack_from("<i", payload, 1)[0])
    if code == PONG:
        _exact(payload, 5, "PONG")
        return Pong(struct.unpack_from("<I", payload, 1)[0])
    if code == SYSTEM:
        _exact(payload, 5, "SYSTEM")
        return SystemMessage(struct.unpack_from("<I", payload, 1)[0])
    if code == REPLY:
        return _decode_reply(payload)
    if code == DATA:
        return _decode_data(payload)
    raise DecodeError(f"unknown response code 0x{code:02X}")


def _decode_reply(payload: bytes) -> Reply:
    if len(payload) < DATA_HEADER_LEN:
        raise DecodeError(f"REPLY shorter than its {DATA_HEADER_LEN}-byte header")
    _, datatype, content_id, info, count = struct.unpack_from("<BBIII", payload)
    size = ELEMENT_SIZE.get(datatype)
    if size is None:
        raise DecodeError(f"REPLY with unknown datatype 0x{datatype:02X}")
    body_end = DATA_HEADER_LEN + count * size
    trailer = len(payload) - body_end
    if trailer not in (0, 1):  # the firmware appends one element-size byte to BYTE/STRING/FLOAT replies
        raise DecodeError(f"REPLY count {count} does not fit its {len(payload)} bytes")
    body = payload[DATA_HEADER_LEN:body_end]
    values: tuple[float, ...] | tuple[int, ...] | bytes
    if datatype == DT_FLOAT:
        values = tuple(float(v) for v in np.frombuffer(body, dtype="<f4"))
    elif datatype == DT_INT:
        values = tuple(int(v) for v in np.frombuffer(body, dtype="<i4"))
    else:
        values = bytes(body)
    return Reply(datatype, content_id, info, values)


def _decode_data(payload: bytes) -> DataFloat:
    if len(payload) < DATA_HEADER_LEN or payload[1] != DT_FLOAT:
        raise DecodeError("DATA that is not a float frame")
    _, _, content_id, counter, n = struct.unpack_from("<BBIII", payload)
    if n > MAX_FLOATS or len(payload) != DATA_HEADER_LEN + 4 * n:
        raise DecodeError(f"radar frame says {n} floats in {len(payload)} bytes")
    values = np.frombuffer(payload, dtype="<f4", offset=DATA_HEADER_LEN, count=n).copy()
    if not plausible_floats(values):
        raise DecodeError("radar frame with implausible float values")
    return DataFloat(content_id, counter, values)
