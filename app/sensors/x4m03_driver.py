"""X4M03 driver over pyserial: connect, configure, stream frames, match replies, recover from unplugging.

Sequence (reference §7, the official examples' order; the thesis settings by default)::

    open, flush → ping until PONG ready → x4driver_init → downconversion, dac_min, dac_max, iterations,
    tx_center_frequency, tx_power, pps, (prf_div), frame_area_offset, frame_area → get_frame_area,
    get_frame_bin_count → set_fps(fps) → get_fps (the measured rate, e.g. 10.032 Hz)

Commands go one at a time; the reader thread keeps delivering frames while a command waits, and the
reply is matched to it by kind (ACK/ERROR for SET and INIT, PONG for ping, REPLY with the queried
parameter ID for GET). A reply nobody waits for is counted and ignored. All waiting is on the loop clock.

Frames carry the device's frame counter: a gap is counted as dropped frames (the counter restarting after
a reconnect is not), and the loop time they were measured: received minus ``frame_latency_s`` (by
default half the sweep, iterations·pps·(dac_max − dac_min + 1)/PRF = 48 ms with the thesis settings — an
estimate; the firmware's own processing delay is unknown). They reach the consumer through a bounded
latest-wins queue.

``run()`` is the long-lived task: connect, stream, and on a lost port (or a device that stopped
answering) close, wait ``reconnect_interval_s`` and start over, until cancelled; then it stops the
stream (fps 0) and closes the port. A device that refuses a setting is a configuration error: ``run``
raises it instead of retrying.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from dataclasses import dataclass, field

from app.clock import Clock, LoopClock
from app.messages import RadarFrame, RangeAxis
from app.queues import LatestQueue
from app.sensors import x4m03_commands as cmd
from app.sensors.radar import RadarCommandError, RadarDisconnected, RadarError, RadarNotReady, RadarTimeout
from app.sensors.x4m03_codec import Ack, DataFloat, ErrorReply, Message, Pong, Reply, SystemMessage, encode_packet
from app.sensors.x4m03_commands import X4Param
from app.sensors.x4m03_frame_area import BASEBAND_BIN_M, axis_from_frame_area
from app.sensors.x4m03_link import SerialLink
from app.sensors.x4m03_parser import ParserStats, X4M03Parser
from app.settings import RadarSettings

PING_RETRY_S = 0.1
STOP_TIMEOUT_S = 0.5


@dataclass(slots=True)
class RadarStats:
    frames: int = 0
    dropped_frames: int = 0  # gaps in the device's frame counter
    queue_drops: int = 0  # frames dropped because the consumer was slower than the radar
    rejected_frames: int = 0  # frames with the wrong size, or before the range axis was known
    connects: int = 0
    connect_failures: int = 0  # attempts of run() that failed (port missing, device not answering)
    disconnects: int = 0
    command_timeouts: int = 0
    unexpected_replies: int = 0
    system_messages: int = 0
    parser: ParserStats = field(default_factory=ParserStats)


Expect = Callable[[Message], bool]


def _ack(m: Message) -> bool:
    return isinstance(m, Ack | ErrorReply)


def _pong(m: Message) -> bool:
    return isinstance(m, Pong | ErrorReply)


def _reply_to(param: X4Param) -> Expect:
    return lambda m: isinstance(m, ErrorReply) or (isinstance(m, Reply) and m.content_id == param)


class X4M03Radar:
    """The ``Radar`` implementation for a Novelda X4M03 (XEP firmware) on a serial port."""

    def __init__(self, settings: RadarSettings, clock: Clock | None = None) -> None:
        self.settings = settings
        self.port = settings.port
        self.clock: Clock = clock if clock is not None else LoopClock()
        self.stats = RadarStats()
        self.fps_hz: float | None = None  # the rate the device reports running at
        self._axis: RangeAxis | None = None
        self._parser = X4M03Parser()
        self.stats.parser = self._parser.stats
        self._link: SerialLink | None = None
        self._queue: LatestQueue[RadarFrame] = LatestQueue(settings.queue_size)
        self._pending: tuple[asyncio.Future[Message], Expect] | None = None
        self._lock = asyncio.Lock()
        self._lost: asyncio.Event | None = None
        self._last_counter: int | None = None
        # A frame is measured over its sweep and sent after it: stamp it at the sweep's middle [I].
        latency_s = settings.frame_latency_s
        self.frame_latency_s = settings.sweep_s() / 2.0 if latency_s is None else latency_s

    # ------------------------------------------------------------------------------------------ lifecycle

    @property
    def axis(self) -> RangeAxis | None:
        return self._axis

    @property
    def connected(self) -> bool:
        return self._link is not None and self._lost is not None and not self._lost.is_set()

    async def open(self) -> None:
        """Open the port and start reading (raises ``RadarDisconnected`` when it cannot be opened)."""
        loop = asyncio.get_running_loop()
        await self._close_link()
        self._lost = asyncio.Event()
        self._last_counter = None
        self._axis = None
        lost = self._lost

        def on_messages(messages: list[Message]) -> None:
            if self._lost is lost:  # not a late batch from a port already closed
                self._on_messages(messages)

        def on_lost(error: RadarDisconnected) -> None:
            if self._lost is lost:
                self._on_lost(error)

        link = SerialLink(self.port, self.settings.baudrate, self._parser, loop, on_messages, on_lost)
        await asyncio.to_thread(link.open)
        self._link = link
        self.stats.connects += 1

    async def connect(self) -> RangeAxis:
        """Open, wait until the device is ready, configure it; returns the range axis it reports."""
        await self.open()
        await self.wait_ready()
        return await self.configure()

    async def wait_ready(self) -> None:
        """Ping until PONG ready (boot messages can be missed; ping is the readiness check)."""
        deadline_s = self.clock.now_s() + self.settings.ready_timeout_s
        last: int | None = None
        while True:
            try:
                pong = await self.command("ping", cmd.ping(), _pong, min(1.0, self.settings.command_timeout_s))
                assert isinstance(pong, Pong)
                if pong.ready:
                    return
                last = pong.value
            except RadarTimeout:
                pass
            if self.clock.now_s() >= deadline_s:
                raise RadarNotReady(self.port, last, self.settings.ready_timeout_s)
            await self.clock.sleep(PING_RETRY_S)

    async def configure(self) -> RangeAxis:
        """x4driver_init, the settings in the firmware's order, then read back the quantised frame area."""
        s = self.settings
        await self.command("x4driver_init", cmd.x4driver_init(), _ack, s.init_timeout_s)
        steps: list[tuple[X4Param, tuple[float, ...]]] = [
            (X4Param.DOWNCONVERSION, (s.downconversion,)),
            (X4Param.DAC_MIN, (s.dac_min,)),
            (X4Param.DAC_MAX, (s.dac_max,)),
            (X4Param.ITERATIONS, (s.iterations,)),
            (X4Param.TX_CENTER_FREQUENCY, (s.tx_center_frequency,)),
            (X4Param.TX_POWER, (s.tx_power,)),
            (X4Param.PULSES_PER_STEP, (s.pulses_per_step,)),
        ]
        if s.prf_div is not None:
            steps.append((X4Param.PRF_DIV, (s.prf_div,)))
        steps += [
            (X4Param.FRAME_AREA_OFFSET, (s.frame_area_offset_m,)),
            (X4Param.FRAME_AREA, (s.frame_area_start_m, s.frame_area_end_m)),
        ]
        for param, values in steps:
            await self.set(param, *values)
        start_m, end_m = await self.get_floats(X4Param.FRAME_AREA)
        try:
            (bins,) = await self.get_ints(X4Param.FRAME_BIN_COUNT)
        except RadarCommandError:  # XEP < 3.3 has no FRAMEBINCOUNT: count the bins of the reported area
            bins = round((end_m - start_m) / BASEBAND_BIN_M) + 1
        self._axis = axis_from_frame_area(start_m, end_m, int(bins))
        return self._axis

    async def start_streaming(self) -> float:
        """set_fps; returns the rate the device reports (get_fps), also kept in ``fps_hz``."""
        await self.set(X4Param.FPS, self.settings.fps_hz)
        (self.fps_hz,) = await self.get_floats(X4Param.FPS)
        return self.fps_hz

    async def stop_streaming(self) -> None:
        """set_fps(0); frames already in flight keep arriving and are delivered."""
        await self.set(X4Param.FPS, 0.0)

    async def close(self) -> None:
        """Stop streaming (best effort, briefly) and close the port."""
        if self.connected:
            try:
                await self.command("set FPS 0", cmd.x4_set(X4Param.FPS, 0.0), _ack, STOP_TIMEOUT_S)
            except RadarError:
                pass
        await self._close_link()

    async def run(self) -> None:
        """Connect, stream, reconnect after losses, until cancelled (then stop and close)."""
        try:
            while True:
                try:
                    await self.connect()
                    await self.start_streaming()
                    assert self._lost is not None
                    await self._lost.wait()
                except RadarCommandError:
                    raise
                except (RadarDisconnected, RadarTimeout, RadarNotReady):
                    self.stats.connect_failures += 1
                await self._close_link()
                await self.clock.sleep(self.settings.reconnect_interval_s)
        finally:
            await self.close()

    async def next_frame(self) -> RadarFrame:
        """The oldest queued frame; waits for one (across reconnects) while ``run`` keeps the radar going."""
        return await self._queue.get()

    # ------------------------------------------------------------------------------------------- commands

    async def command(self, name: str, payload: bytes, expect: Expect, timeout_s: float | None = None) -> Message:
        """Send one command and wait for its reply; raises RadarTimeout / RadarCommandError / RadarDisconnected."""
        timeout_s = self.settings.command_timeout_s if timeout_s is None else timeout_s
        async with self._lock:
            link = self._link
            if link is None or not self.connected:
                raise RadarDisconnected(self.port, f"cannot send {name}: not connected")
            future: asyncio.Future[Message] = asyncio.get_running_loop().create_future()
            self._pending = (future, expect)
            try:
                await asyncio.to_thread(link.write, encode_packet(payload))
                reply = await asyncio.wait_for(future, timeout_s)
            except TimeoutError:
                self.stats.command_timeouts += 1
                raise RadarTimeout(self.port, name, timeout_s) from None
            finally:
                self._pending = None
        if isinstance(reply, ErrorReply):
            raise RadarCommandError(self.port, name, reply.code, cmd.error_meaning(reply.code))
        return reply

    async def set(self, param: X4Param, *values: float) -> None:
        await self.command(f"set {param.name} {', '.join(f'{v:g}' for v in values)}", cmd.x4_set(param, *values), _ack)

    async def get_floats(self, param: X4Param) -> tuple[float, ...]:
        reply = await self.command(f"get {param.name}", cmd.x4_get(param), _reply_to(param))
        assert isinstance(reply, Reply)
        return tuple(float(v) for v in reply.values)

    async def get_ints(self, param: X4Param) -> tuple[int, ...]:
        reply = await self.command(f"get {param.name}", cmd.x4_get(param), _reply_to(param))
        assert isinstance(reply, Reply)
        return tuple(int(v) for v in reply.values)

    # ------------------------------------------------------------------------- called by the reader thread

    def _on_messages(self, messages: list[Message]) -> None:
        now_s = self.clock.now_s()
        for m in messages:
            if isinstance(m, DataFloat):
                self._on_frame(now_s, m)
            elif isinstance(m, SystemMessage):
                self.stats.system_messages += 1
            elif self._pending is not None and not self._pending[0].done() and self._pending[1](m):
                self._pending[0].set_result(m)
            else:
                self.stats.unexpected_replies += 1

    def _on_frame(self, now_s: float, m: DataFloat) -> None:
        axis, queue = self._axis, self._queue
        if axis is None or m.values.size != 2 * axis.bins:
            self.stats.rejected_frames += 1
            return
        if self._last_counter is not None and m.frame_counter > self._last_counter:
            self.stats.dropped_frames += m.frame_counter - self._last_counter - 1
        self._last_counter = m.frame_counter
        self.stats.frames += 1
        queue.put(RadarFrame.from_floats(now_s - self.frame_latency_s, m.frame_counter, axis, m.values))
        self.stats.queue_drops = queue.dropped

    def _on_lost(self, error: RadarDisconnected) -> None:
        self.stats.disconnects += 1
        if self._lost is not None:
            self._lost.set()
        if self._pending is not None and not self._pending[0].done():
            self._pending[0].set_exception(error)

    async def _close_link(self) -> None:
        link, self._link = self._link, None
        if self._lost is not None:
            self._lost.set()
        if link is not None:
            await asyncio.to_thread(link.close)
