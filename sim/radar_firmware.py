"""The X4M03's XEP firmware as a state machine: host bytes in, device bytes out, on a clock you pass in.

Behaviour (``reference/x4m03-protocol.md`` §3–§7, §10.6): after power-on it sends SYSTEM BOOTING, then
READY ``ready_delay_s`` later; before READY a ping answers PONG not-ready. Every SET and INIT gets ACK or
ERROR(x4driver code) after the firmware's checks; GETs get REPLY FLOAT/INT/BYTE (with the firmware's
trailing size byte); unknown commands and SETMODE/LOADAPP get ERROR 1; a packet with a bad checksum gets
*nothing*. set_fps > 0 streams frames at the measured rate (10 → 10.032 Hz) with a counter, as NoEscape
packets (or the legacy escaped form); fps 0 stops. module_reset: ACK, then a reboot 0.5 s later.

Its own host-packet receiver is written from the reference independently of the app's parser (on
purpose: the two check each other). Fault switches (``FirmwareFaults``, changeable at any time): garbage
bytes before packets, frames dropped (the counter still advances), corrupted checksums on escaped replies,
and the next N host packets corrupted on the way in (so the device stays silent).
Emulator limitation: downconversion 0 (RF frames) is answered ERROR 2, "not supported".
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from app.messages import RangeAxis
from app.sensors import x4m03_codec as codec
from app.sensors import x4m03_commands as cmd
from app.sensors.x4m03_commands import X4Param
from app.sensors.x4m03_frame_area import quantise_frame_area

MEASURED_FPS = {10: 10.032052556, 17: 17.049378771}  # get_fps for 1..34 Hz comes from a table [C]; others [I]
RESET_DELAY_S = 0.5
INT_PARAMS = (X4Param.ITERATIONS, X4Param.PULSES_PER_STEP, X4Param.DAC_MIN, X4Param.DAC_MAX, X4Param.FRAME_BIN_COUNT)
BYTE_PARAMS = (X4Param.DOWNCONVERSION, X4Param.DAC_STEP, X4Param.TX_POWER, X4Param.TX_CENTER_FREQUENCY, X4Param.PRF_DIV)

FrameSource = Callable[[float, RangeAxis], np.ndarray]  # (t_s, axis) → complex baseband (I + jQ)


def measured_fps(requested_hz: float) -> float:
    """The rate the X4 timer really runs for a requested fps (truncated to an integer; (0, 1) → 1)."""
    whole = max(1, int(requested_hz))
    return MEASURED_FPS.get(whole, whole * 1.0032)


@dataclass(slots=True)
class FirmwareConfig:
    boot_delay_s: float = 1.0  # power-on → BOOTING
    ready_delay_s: float = 1.0  # BOOTING → READY
    escaped_frames: bool = False  # legacy (XEP 2.x) escaped DataFloat instead of NoEscape


@dataclass(slots=True)
class FirmwareFaults:
    garbage_probability: float = 0.0  # per outgoing packet: random bytes in front of it
    garbage_max_bytes: int = 40
    drop_probability: float = 0.0  # per frame: not sent (the counter advances)
    corrupt_reply_probability: float = 0.0  # per escaped reply: checksum flipped
    corrupt_next_commands: int = 0  # the next N host packets arrive corrupted: no reply at all


@dataclass(slots=True)
class X4Settings:
    fps_hz: float = 0.0
    pulses_per_step: int = 300
    iterations: int = 16
    downconversion: int = 1
    area_m: tuple[float, float] = (0.0, 9.88)  # requested; x4driver_init resets it
    dac_step: int = 0
    dac_min: int = 949
    dac_max: int = 1100
    offset_m: float = 0.18
    tx_center_frequency: int = 3
    tx_power: int = 2
    prf_div: int = 16


@dataclass(slots=True)
class FirmwareLog:
    """What the device saw and did (for tests and the CLI)."""

    commands: list[tuple[str, tuple[float, ...]]] = field(default_factory=list)  # (name, values) in order
    crc_errors: int = 0
    frames_sent: int = 0
    frames_dropped: int = 0
    boots: int = 0


class X4M03Firmware:
    def __init__(
        self,
        frames: FrameSource,
        config: FirmwareConfig | None = None,
        faults: FirmwareFaults | None = None,
        seed: int = 0,
    ) -> None:
        self.frames = frames
        self.config = config if config is not None else FirmwareConfig()
        self.faults = faults if faults is not None else FirmwareFaults()
        self.log = FirmwareLog()
        self._rng = np.random.default_rng(seed)
        self.x4 = X4Settings()
        self.ready = False
        self.counter = 0
        self._rx = bytearray()
        self._in_packet = False
        self._events: list[tuple[float, str]] = []  # (due t_s, "booting" | "ready" | "reset")
        self._next_frame_s: float | None = None

    @property
    def axis(self) -> RangeAxis:
        return quantise_frame_area(*self.x4.area_m, self.x4.offset_m)

    # ------------------------------------------------------------------------------------------ timing

    def power_on(self, t_s: float) -> None:
        self.x4, self.ready, self.counter, self._next_frame_s = X4Settings(), False, 0, None
        self._rx.clear()
        self._in_packet = False
        self._events = [(t_s + self.config.boot_delay_s, "booting")]

    def next_due_s(self) -> float | None:
        times = [t for t, _ in self._events] + ([self._next_frame_s] if self._next_frame_s is not None else [])
        return min(times) if times else None

    def poll(self, t_s: float) -> bytes:
        """Boot messages and frames due by ``t_s``."""
        out = bytearray()
        while self._events and min(self._events)[0] <= t_s:
            due, what = min(self._events)
            self._events.remove((due, what))
            out += self._event(due, what)
        while self._next_frame_s is not None and self._next_frame_s <= t_s:
            out += self._frame(self._next_frame_s)
            self._next_frame_s += 1.0 / measured_fps(self.x4.fps_hz)
        return bytes(out)

    def _event(self, t_s: float, what: str) -> bytes:
        if what == "booting":
            self.log.boots += 1
            self._events.append((t_s + self.config.ready_delay_s, "ready"))
            return self._send(codec.system_payload(codec.SYSTEM_BOOTING))
        if what == "ready":
            self.ready = True
            return self._send(codec.system_payload(codec.SYSTEM_READY))
        self.power_on(t_s)  # "reset"
        return b""

    def _frame(self, t_s: float) -> bytes:
        self.counter += 1
        if self.faults.drop_probability > 0.0 and self._rng.random() < self.faults.drop_probability:
            self.log.frames_dropped += 1
            return b""
        baseband = self.frames(t_s, self.axis)
        values = np.concatenate([baseband.real, -baseband.imag]).astype(np.float32)  # Q negated (fw 2.1.0)
        payload = codec.data_float_payload(self.counter, values)
        self.log.frames_sent += 1
        wire = codec.encode_packet(payload) if self.config.escaped_frames else codec.encode_noescape(payload)
        return self._garbage() + wire

    # ----------------------------------------------------------------------------------------- receiving

    def receive(self, data: bytes, t_s: float) -> bytes:
        """Host bytes in; the replies to every complete command out."""
        out = bytearray()
        escaped = False
        for b in data:
            if not self._in_packet:
                if b == codec.START:
                    self._in_packet, self._rx, escaped = True, bytearray(), False
                continue  # bytes between packets are ignored
            if escaped:
                self._rx.append(b)
                escaped = False
            elif b == codec.ESCAPE:
                escaped = True
            elif b == codec.START:
                self._rx = bytearray()  # restart
            elif b == codec.END:
                self._in_packet = False
                out += self._packet(bytes(self._rx), t_s)
            else:
                self._rx.append(b)
        return bytes(out)

    def _packet(self, body: bytes, t_s: float) -> bytes:
        if self.faults.corrupt_next_commands > 0 and body:
            self.faults.corrupt_next_commands -= 1
            body = bytes([body[0] ^ 0x01]) + body[1:]  # a bit flipped on the wire
        if not body:
            return b""
        crc = codec.START
        for b in body:
            crc ^= b
        if crc != 0:  # XOR of 0x7D, payload and crc must be 0: else drop it silently, as the firmware does
            self.log.crc_errors += 1
            return b""
        return self._command(body[:-1], t_s)

    def _command(self, p: bytes, t_s: float) -> bytes:
        op = p[0] if p else -1
        if op == cmd.PING and len(p) == 5:
            self.log.commands.append(("ping", ()))
            return self._send(codec.pong_payload(codec.PONG_READY if self.ready else codec.PONG_NOT_READY))
        if not self.ready:
            return b""  # still booting: the command processor is not running yet
        if op == cmd.MOD_RESET:
            self.log.commands.append(("module_reset", ()))
            self._next_frame_s = None
            self._events.append((t_s + RESET_DELAY_S, "reset"))
            return self._send(codec.ack_payload())
        if op == cmd.X4DRIVER and len(p) >= 2:
            return self._x4driver(p, t_s)
        if op == cmd.DIR_COMMAND and len(p) == 3 and p[1] == cmd.SYSTEM_INFO and p[2] in (2, 3):
            text = b"X4M03" if p[2] == 2 else b"3.4.8"
            return self._send(codec.reply_payload(codec.DT_STRING, cmd.SYSTEM_INFO, text, info=p[2]))
        self.log.commands.append((f"unknown 0x{op:02X}", ()))
        return self._error(1)

    def _x4driver(self, p: bytes, t_s: float) -> bytes:
        sub = p[1]
        if sub == cmd.X4_INIT and len(p) == 2:
            self.log.commands.append(("x4driver_init", ()))
            self.x4 = X4Settings()
            self._next_frame_s = None
            return self._send(codec.ack_payload())
        if sub not in (cmd.X4_SET, cmd.X4_GET) or len(p) < 6:
            return self._error(1)
        try:
            param = X4Param(struct.unpack_from("<I", p, 2)[0])
        except ValueError:
            return self._error(1)
        if sub == cmd.X4_GET:
            return self._get(param) if len(p) == 6 else self._error(1)
        fmt = "<" + cmd.SET_FORMAT.get(param, "")
        if fmt == "<" or len(p) != 6 + struct.calcsize(fmt):
            return self._error(1)
        values = struct.unpack_from(fmt, p, 6)
        self.log.commands.append((f"set {param.name}", tuple(float(v) for v in values)))
        code = self._set(param, values, t_s)
        return self._send(codec.ack_payload()) if code == 0 else self._error(code)

    def _set(self, param: X4Param, values: tuple[float, ...], t_s: float) -> int:
        """Apply a SET as x4driver does; 0 or the x4driver error code."""
        x4, v = self.x4, values[0]
        if param == X4Param.FPS:
            if not math.isfinite(v) or v < 0:
                return 1
            x4.fps_hz = float(v)
            self._next_frame_s = t_s + 1.0 / measured_fps(v) if v > 0 else None
        elif param in (X4Param.DAC_MIN, X4Param.DAC_MAX):
            if v > 0x7FF:
                return 1
            setattr(x4, "dac_min" if param == X4Param.DAC_MIN else "dac_max", int(v))
        elif param == X4Param.FRAME_AREA:
            if not all(map(math.isfinite, values)) or values[0] > values[1]:
                return 17
            x4.area_m = (float(values[0]), float(values[1]))
        elif param == X4Param.FRAME_AREA_OFFSET:
            x4.offset_m = float(v)
        elif param == X4Param.DOWNCONVERSION:
            return 0 if v == 1 else 2
        elif param == X4Param.TX_POWER:
            if not 0 <= v <= 3:
                return 21
            x4.tx_power = int(v)
        elif param == X4Param.TX_CENTER_FREQUENCY:
            if v not in (3, 4):
                return 20
            x4.tx_center_frequency = int(v)
        elif param == X4Param.PRF_DIV:
            if v < 4:
                return 18
            x4.prf_div = int(v)
        elif param == X4Param.DAC_STEP:
            if v > 3:
                return 12
            x4.dac_step = int(v)
        elif param == X4Param.ITERATIONS:
            x4.iterations = int(v) & 0xFF
        elif param == X4Param.PULSES_PER_STEP:
            x4.pulses_per_step = int(v) & 0xFFFF
        else:
            return 2
        return 0

    def _get(self, param: X4Param) -> bytes:
        self.log.commands.append((f"get {param.name}", ()))
        x4, axis = self.x4, self.axis
        floats = {
            X4Param.FRAME_AREA: [axis.start_m, axis.end_m],
            X4Param.FRAME_AREA_OFFSET: [x4.offset_m],
            X4Param.FPS: [measured_fps(x4.fps_hz) if x4.fps_hz > 0 else 0.0],
        }
        ints = {
            X4Param.ITERATIONS: x4.iterations,
            X4Param.PULSES_PER_STEP: x4.pulses_per_step,
            X4Param.DAC_MIN: x4.dac_min,
            X4Param.DAC_MAX: x4.dac_max,
            X4Param.FRAME_BIN_COUNT: axis.bins,
        }
        small = {
            X4Param.DOWNCONVERSION: x4.downconversion,
            X4Param.DAC_STEP: x4.dac_step,
            X4Param.TX_POWER: x4.tx_power,
            X4Param.TX_CENTER_FREQUENCY: x4.tx_center_frequency,
            X4Param.PRF_DIV: x4.prf_div,
        }
        if param in floats:
            return self._send(codec.reply_payload(codec.DT_FLOAT, param, floats[param]))
        if param in ints:
            return self._send(codec.reply_payload(codec.DT_INT, param, [ints[param]]))
        if param in small:
            return self._send(codec.reply_payload(codec.DT_BYTE, param, bytes([small[param]])))
        return self._error(1)

    # ------------------------------------------------------------------------------------------ sending

    def _error(self, code: int) -> bytes:
        return self._send(codec.error_payload(code))

    def _send(self, payload: bytes) -> bytes:
        wire = bytearray(codec.encode_packet(payload))
        p = self.faults.corrupt_reply_probability
        if p > 0.0 and self._rng.random() < p:  # no draw when off: the other faults' sequence stays seeded
            wire[-2] ^= 0x01  # the crc byte (an escaped crc stays escaped: 7D/7E/7F ^ 1 is 7C/7F/7E)
        return self._garbage() + bytes(wire)

    def _garbage(self) -> bytes:
        f = self.faults
        if f.garbage_probability <= 0.0 or self._rng.random() >= f.garbage_probability:
            return b""
        return self._rng.integers(0, 256, int(self._rng.integers(1, f.garbage_max_bytes + 1)), dtype=np.uint8).tobytes()
