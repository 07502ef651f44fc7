"""X4M03 host → device commands: opcodes, parameter IDs and payload builders (``reference/x4m03-protocol.md`` §4).

Builders return the *payload*; :func:`app.sensors.x4m03_codec.encode_packet` frames it. Parameter IDs go
out as u32; the value's width depends on the parameter (u8, u32 or f32), as the firmware parses it.
"""

from __future__ import annotations

import struct
from enum import IntEnum
from typing import Final

# Opcodes
PING: Final = 0x01
MOD_SETMODE: Final = 0x20
MOD_LOADAPP: Final = 0x21
MOD_RESET: Final = 0x22
X4DRIVER: Final = 0x50
DIR_COMMAND: Final = 0x90

# X4DRIVER sub-commands
X4_SET: Final = 0x10
X4_GET: Final = 0x11
X4_INIT: Final = 0x20

PING_VALUE: Final = 0xEEAAEAAE
SYSTEM_INFO: Final = 0x58


class X4Param(IntEnum):
    """X4DRIVER parameter IDs."""

    FPS = 0x10
    PULSES_PER_STEP = 0x11
    ITERATIONS = 0x12
    DOWNCONVERSION = 0x13
    FRAME_AREA = 0x14
    DAC_STEP = 0x15
    DAC_MIN = 0x16
    DAC_MAX = 0x17
    FRAME_AREA_OFFSET = 0x18
    ENABLE = 0x19
    TX_CENTER_FREQUENCY = 0x20
    TX_POWER = 0x21
    PRF_DIV = 0x25
    FRAME_BIN_COUNT = 0x26


# How each SET value is packed (firmware parser widths): u8 "B", u32 "I", f32 "f", two f32 "ff".
SET_FORMAT: Final[dict[X4Param, str]] = {
    X4Param.FPS: "f",
    X4Param.PULSES_PER_STEP: "I",
    X4Param.ITERATIONS: "I",
    X4Param.DOWNCONVERSION: "B",
    X4Param.FRAME_AREA: "ff",
    X4Param.DAC_STEP: "I",
    X4Param.DAC_MIN: "I",
    X4Param.DAC_MAX: "I",
    X4Param.FRAME_AREA_OFFSET: "f",
    X4Param.ENABLE: "B",
    X4Param.TX_CENTER_FREQUENCY: "B",
    X4Param.TX_POWER: "B",
    X4Param.PRF_DIV: "B",
}

# x4driver status codes (ERROR replies to X4DRIVER commands) and MCP codes, for error messages.
X4_ERRORS: Final = {
    1: "NOK / not recognised",
    2: "not supported",
    3: "busy",
    4: "PIF timeout",
    9: "frame-ready timeout",
    11: "buffer too small",
    12: "invalid DAC step",
    16: "frame area too large",
    17: "frame-area end out of scope",
    18: "prf_div too small",
    20: "invalid center frequency",
    21: "invalid tx power",
}


def error_meaning(code: int) -> str:
    return X4_ERRORS.get(
        code, "invalid configuration" if 22 <= code <= 26 else "PLL lock fail" if 27 <= code <= 29 else "unknown"
    )


def ping() -> bytes:
    return struct.pack("<BI", PING, PING_VALUE)


def module_reset() -> bytes:
    return bytes([MOD_RESET])


def x4driver_init() -> bytes:
    return bytes([X4DRIVER, X4_INIT])


def set_sensor_mode(mode: int) -> bytes:
    """X4M200/300 only: XEP answers ERROR 1 (STOP 0x13, MANUAL 0x12)."""
    return bytes([MOD_SETMODE, mode])


def x4_set(param: X4Param, *values: float) -> bytes:
    """``50 10 | u32 id | value`` packed as the firmware reads that parameter."""
    fmt = SET_FORMAT[param]
    if len(values) != len(fmt):
        raise ValueError(f"{param.name} takes {len(fmt)} value(s), got {len(values)}")
    packed = struct.pack("<" + fmt, *(int(v) if f in "BI" else float(v) for f, v in zip(fmt, values, strict=True)))
    return struct.pack("<BBI", X4DRIVER, X4_SET, int(param)) + packed


def x4_get(param: X4Param) -> bytes:
    return struct.pack("<BBI", X4DRIVER, X4_GET, int(param))


def get_system_info(code: int) -> bytes:
    return bytes([DIR_COMMAND, SYSTEM_INFO, code])
